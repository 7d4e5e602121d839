"""Claims against truths the model did not make: the loop-closed model of a simulated iiwa whose every
fixed transform carries a small rigid error (written by the simulator in another form than the fit's),
asked through `remaster predict` where the marker is at random configurations across the joint limits
and inside the measured joint ranges, and its workspace claims (the certificate's p95 bound) in both.

Run from the repository root: python benchmarks/bench_truth_claims.py [seed ...] (default 21).
Two campaigns of the twin's size (36 poses / 173 configurations to fit, 32 / 156 to validate), one
laser tracker (10 um): joint 3 moving (drawn per pose) and joint 3 held at 0 (the paper's planner).
Printed per campaign: the effects added, validation RMS per axis against the noise; across the limits
and inside the measured ranges the true error's 95th percentile, the median per-command bound, and the
share of configurations within their bound; the workspace claims' pooled p95 and p95 bound against the
true 95th percentile of the registered error in both.
Writes benchmarks/results/truth_claims.json.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.truth_claims import check  # noqa: E402
from remaster.campaigns.arm_kinds import chain_of, iiwa_rigid_link_errors  # noqa: E402

SIZES = {
    "optimization": {"poses": 36, "configurations": 173},
    "validation": {"poses": 32, "configurations": 156},
}


def scenario(seed: int, q3) -> dict:
    spec = iiwa_rigid_link_errors(seed=seed)
    spec["name"] = f"rigid-link-errors-q3-{q3}"
    spec["plan"]["sets"] = SIZES
    spec["plan"]["q3"] = q3
    return spec


def main() -> None:
    seeds = [int(s) for s in sys.argv[1:]] or [21]
    rows = []
    for seed in seeds:
        for q3 in ("free", 0.0):
            spec = scenario(seed, q3)
            result = check(spec, chain_of(spec, REPO), "laser_tracker")
            rows.append({"seed": seed, "joint_3": "moving" if q3 == "free" else "held at 0", **result.summary()})
            print(json.dumps(rows[-1]), flush=True)
    out = REPO / "benchmarks" / "results" / "truth_claims.json"
    out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
