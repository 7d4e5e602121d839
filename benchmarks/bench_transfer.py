"""Calibrations that transfer: does a calibration predict another design of the same robot within
the bound it states there?

One simulated iiwa (zero-offsets plus a truth the fit's parametrization does not hold: rigid link
errors, or joint compliance under a payload; the same true robot for every design of a seed) is
measured three ways: Latin-hypercube poses with joint 3 held ("q3 held"), every joint turning
("every joint"), and joint 3 held with the tracker set up elsewhere ("tracker moved": another
position, so other poses pass its line of sight). Each campaign goes through the pipeline's own stages
in-process (`truth_claims.check`), and its calibration's `remaster predict` (loop-closed model, its
own sensor frame) is held to the truth at the validation commands of each OTHER design of its seed:

- the share of those commands whose true error exceeds the per-command 95 % bound (target: at most
  10 %);
- the RMS true error there of the loop-closed model and of the zero-offset model (its worst
  transfer should be no worse than the zero-offset model's).

Writes benchmarks/results/transfer.json and transfer.md and the table into docs/validation.md between
its bench_transfer markers. From the repository root:
    .venv/bin/python benchmarks/bench_transfer.py [--seeds N] [--first SEED] [--jobs J]
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import publish  # noqa: E402
from benchmarks.truth_claims import REPO, check  # noqa: E402
from remaster.campaigns import scenario  # noqa: E402
from remaster.campaigns.arm_kinds import TRACKER, chain_of, iiwa_scenario  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
TRUTHS = {
    "rigid links": {"link_errors": {"translation_std": 1.0e-4, "rotation_std": 2.0e-4, "seed": 9}},
    "compliance": {
        "joint_compliance": [0.0, 2.5e-5, 0.0, 3.0e-5, 0.0, 5.0e-5, 0.0],
        "payload": {"mass": 2.5, "com": [0.0, 0.0, 0.03]},
    },
}
MOVED_TRACKER = {"laser_tracker": {**TRACKER, "position": [0.4, -1.7, 1.2]}}
DESIGNS = {"q3 held": ({}, None), "every joint": ({"q3": "free"}, None), "tracker moved": ({}, MOVED_TRACKER)}
MAX_OUTSIDE = 0.10


def spec_of(truth: str, design: str, seed: int) -> dict:
    plan, sensors = DESIGNS[design]
    return iiwa_scenario(f"transfer-{seed}", seed=seed, truth=TRUTHS[truth], plan=plan, sensors=sensors)


def validation_q(truth: str, design: str, seed: int) -> np.ndarray:
    """The validation commands (m, N) rad of one design (the simulator is deterministic in its seed)."""
    spec = spec_of(truth, design, seed)
    table = scenario.simulate(spec, chain_of(spec, REPO)).tables["laser_tracker"]
    rows = table[table["set"] == "validation"]
    return rows[[c for c in rows.columns if c.startswith("q") and c[1:].isdigit()]].to_numpy(float)


def one(task: tuple) -> list[dict]:
    """One calibration (truth, design, seed) held to the truth at each other design's validation commands."""
    truth, design, seed = task
    started = time.perf_counter()
    others = [d for d in DESIGNS if d != design]
    q = {d: validation_q(truth, d, seed) for d in others}
    spec = spec_of(truth, design, seed)
    checked = check(
        spec,
        chain_of(spec, REPO),
        "laser_tracker",
        n_random=50,
        draws=400,
        seed=seed,
        elsewhere_q=np.vstack(list(q.values())),
    )
    there, rows, start = checked.elsewhere, [], 0
    for other in others:
        part = slice(start, start + len(q[other]))
        start = part.stop
        rows.append(
            {
                "truth": truth,
                "calibrated_on": design,
                "predicting": other,
                "seed": seed,
                "effects": list(checked.effects),
                "outside_share": float(np.mean(there["error_mm"][part] > there["bound_mm"][part])),
                "loop_rms_mm": float(np.sqrt(np.mean(there["error_mm"][part] ** 2))),
                "paper_rms_mm": float(np.sqrt(np.mean(there["paper_error_mm"][part] ** 2))),
                "bound_median_mm": float(np.median(there["bound_mm"][part])),
                # the calibration's own posterior, its draws taken as the arm: the chance of this transfer's
                # share outside exceeding the target (correlated errors: not zero for a calibrated bound)
                "own_chance_above_target": float(np.mean(np.mean(there["own_outside"][:, part], axis=1) > MAX_OUTSIDE)),
                "seconds": time.perf_counter() - started,
            }
        )
    return rows


def markdown(record: dict) -> str:
    runs = record["runs"]
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_transfer.py`: {record['seeds']} seeds per truth, "
        f"each calibration held to the truth at the validation commands of each other design of its seed.",
        "",
        "| truth | calibrated on | predicting | seeds | outside the bound: mean | max | loop RMS (mm): median | "
        "worst | zero-offset model RMS (mm): worst |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for truth in TRUTHS:
        for design in DESIGNS:
            for other in DESIGNS:
                part = [r for r in runs if (r["truth"], r["calibrated_on"], r["predicting"]) == (truth, design, other)]
                if not part:
                    continue
                outside = np.array([r["outside_share"] for r in part])
                loop = np.array([r["loop_rms_mm"] for r in part])
                lines.append(
                    f"| {truth} | {design} | {other} | {len(part)} | {100 * outside.mean():.1f} % | "
                    f"{100 * outside.max():.0f} % | {np.median(loop):.4f} | {loop.max():.4f} | "
                    f"{max(r['paper_rms_mm'] for r in part):.4f} |"
                )
    outside = np.array([r["outside_share"] for r in runs])
    worse = sum(r["loop_rms_mm"] > r["paper_rms_mm"] for r in runs)
    expected = sum(r.get("own_chance_above_target", np.nan) for r in runs)
    lines += [
        "",
        f"Transfers with more than {100 * MAX_OUTSIDE:.0f} % of the commands outside their bound: "
        f"{int(np.sum(outside > MAX_OUTSIDE))} of {len(runs)} (target: none)"
        + (
            f"; the calibrations' own posteriors (each draw taken as the arm) expect {expected:.1f}: one arm's "
            "errors are correlated across its commands, so a calibrated bound is exceeded at many commands at "
            "once on a share of arms"
            if np.isfinite(expected)
            else ""
        )
        + f". Mean share outside {100 * outside.mean():.1f} %. Transfers where the loop-closed model is "
        f"farther from the truth than the zero-offset model: {worse} of {len(runs)}.",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--first", type=int, default=101)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    tasks = [(t, d, s) for t in TRUTHS for d in DESIGNS for s in range(args.first, args.first + args.seeds)]
    with ProcessPoolExecutor(args.jobs) as pool:
        runs = [row for rows in pool.map(one, tasks) for row in rows]
    record = {"date": date.today().isoformat(), "seeds": args.seeds, "runs": runs}
    publish(RESULTS, "transfer", record, markdown(record), REPO / "docs" / "validation.md")


if __name__ == "__main__":
    main()
