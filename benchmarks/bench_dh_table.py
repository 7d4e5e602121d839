"""The calibrated DH table's least squares, trust region (scipy's `trf`, what it was) against
Levenberg-Marquardt (`lm`, what `calibration.dh_table` runs), side by side on the bundled real UR5:
its DH table, its 1,000 optimization configurations, and link errors of a few tenths of a mm and
hundredths of a degree that DH cannot hold row by row (a tilt between parallel axes), so the table
is fitted by least squares to the calibrated flange poses. Each method runs `REPEAT` times in turn;
the ratio is taken pair by pair.

Run: python benchmarks/bench_dh_table.py   (writes benchmarks/results/dh_table.json)
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import scipy.optimize

from remaster.calibration import dh_table
from remaster.campaigns.folders import read_campaign
from remaster.inference.parameter_blocks import link_labels

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "data" / "raw" / "jacobi-ur5-gts3800"
OUT = ROOT / "benchmarks" / "results" / "dh_table.json"
REPEAT = 3


def calibrated_values(chain, rng) -> dict[str, float]:
    """Zero-offsets of tenths of a degree and link errors of 0.3 mm and 0.02 deg (every joint origin)."""
    values = {f"zero_offsets.q{j + 1}": rng.normal(0.0, np.radians(0.2)) for j in range(chain.n_joints)}
    for _, column, name in link_labels(chain):
        values[name] = rng.normal(0.0, 3e-4 if column < 3 else np.radians(0.02))
    return values


def timed(method: str, chain, dh, values, q) -> tuple[float, dict]:
    """Seconds and the table of `calibrated_dh` with the table's least squares run by `method`."""
    original = scipy.optimize.least_squares

    def with_method(*args, **kwargs):
        return original(*args, **{**kwargs, "method": method})

    scipy.optimize.least_squares = with_method
    try:
        start = time.perf_counter()
        table = dh_table.calibrated_dh(chain, dh, values, q)
        return time.perf_counter() - start, table
    finally:
        scipy.optimize.least_squares = original


def main() -> None:
    campaign = read_campaign(CAMPAIGN, repo_root=ROOT)
    chain, dh = campaign.chain, campaign.robot["dh"]
    q = campaign.sensors["laser_tracker"].q("optimization")
    values = calibrated_values(chain, np.random.default_rng(11))
    pairs = []
    for _ in range(REPEAT):
        t_trf, trf = timed("trf", chain, dh, values, q)
        t_lm, lm = timed("lm", chain, dh, values, q)
        pairs.append({"trf_s": t_trf, "lm_s": t_lm, "ratio": t_trf / t_lm})
    rows = np.abs(np.array(trf["rows"]) - np.array(lm["rows"])).max()
    result = {
        "configurations": len(q),
        "fitted_by_least_squares": not trf["exact"] or bool(trf["not_dh_form"]),
        "pairs": pairs,
        "ratio_min": min(p["ratio"] for p in pairs),
        "ratio_median": float(np.median([p["ratio"] for p in pairs])),
        "largest_row_difference": float(rows),
        "max_position_difference_m": {"trf": trf["max_position_difference_m"], "lm": lm["max_position_difference_m"]},
    }
    OUT.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
