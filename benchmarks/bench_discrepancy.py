"""Drift z between fleet copies of one robot whose model lacks an effect: the paper's Laplace stds
against the pose-clustered sandwich stds (`inference.discrepancy`).

Copies of the bundled kuka-compliance scenario (compliance and a heavy payload the paper's model
lacks; one true robot, new poses and noise per copy, `scenario.copies`), laser tracker: the paper's
model fitted by Laplace on each, and for every identifiable zero-offset the drift z between
consecutive copies, (b - a) / hypot(std_a, std_b), with either std. One robot, so z should spread like
a standard normal: a spread near 1 per joint is an honest std; above, drift flagged where nothing
changed. Targets (printed, not tuned to): every joint's sandwich spread within 0.6-1.5, all joints'
within 0.2 of 1.

Writes benchmarks/results/discrepancy.json and .md and the table into docs/validation.md between its
bench_discrepancy markers. From the repository root:
    .venv/bin/python benchmarks/bench_discrepancy.py [--copies N]
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import publish  # noqa: E402
from benchmarks.truth_claims import REPO  # noqa: E402
from remaster import files  # noqa: E402
from remaster.campaigns import scenario  # noqa: E402
from remaster.campaigns.arm_kinds import IIWA  # noqa: E402
from remaster.campaigns.campaign import sensor_data  # noqa: E402
from remaster.inference import discrepancy, fit  # noqa: E402
from remaster.inference.laplace_report import laplace_fit  # noqa: E402
from remaster.robot import kinematics  # noqa: E402

SCENARIO = REPO / "data" / "simulation" / "kuka-compliance.yaml"
SENSOR = "laser_tracker"
RESULTS = REPO / "benchmarks" / "results"
SPREAD = (0.6, 1.5)  # every joint's sandwich z spread within
OVERALL = 0.2  # all joints' z spread within this of 1


def zero_offset_estimates(chain, copy: dict, seed: int) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """One copy's identifiable zero-offsets: (names, Laplace means, Laplace stds, sandwich stds), rad."""
    out = scenario.simulate(copy, chain, seed)
    meta = out.metadata["sensors"][SENSOR]
    sensor = sensor_data(SENSOR, {**meta, "marker": np.array(meta["marker"])}, out.tables[SENSOR], chain.n_joints, "x")
    model, _, _ = fit.build_model(chain, sensor, fit.register(chain, sensor).t_nr)
    laplace = laplace_fit(model)
    names = list(model.names)
    summary = pd.DataFrame(
        {"parameter": names, "mean": laplace.theta_map, "std": laplace.std, "q2.5": np.nan, "q97.5": np.nan}
    ).assign(status="estimated")
    table, _ = discrepancy.discrepancy_summary(
        model, laplace.theta_map, sensor.table.loc[model.data.rows, "pose"], summary
    )
    offsets = [n for n in names if n.startswith("zero_offsets.")]
    table = table.set_index("parameter").loc[offsets]
    paper = summary.set_index("parameter").loc[offsets, "std"].to_numpy()
    return offsets, table["mean"].to_numpy(float), paper, table["std"].to_numpy(float)


def markdown(record: dict) -> str:
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_discrepancy.py`: {record['copies']} copies of "
        f"kuka-compliance (one robot: new poses and noise per copy), laser tracker, the paper's model by "
        "Laplace; z between consecutive copies of each identifiable zero-offset, its spread (std over the "
        "pairs) with the paper's stds and with the pose-clustered sandwich stds.",
        "",
        "| zero-offset | z spread, paper's stds | z spread, sandwich stds |",
        "|---|---|---|",
    ]
    for name, paper, sandwich in zip(record["parameters"], record["spread_paper"], record["spread_sandwich"]):
        lines.append(f"| {name} | {paper:.2f} | {sandwich:.2f} |")
    within = all(SPREAD[0] < s < SPREAD[1] for s in record["spread_sandwich"])
    overall = abs(record["spread_sandwich_all"] - 1.0) < OVERALL
    lines += [
        "",
        f"Every joint's sandwich spread within {SPREAD[0]}-{SPREAD[1]}: {'pass' if within else 'FAIL'}; all "
        f"joints' {record['spread_sandwich_all']:.2f} (paper's stds {record['spread_paper_all']:.2f}), within "
        f"{OVERALL} of 1: {'pass' if overall else 'FAIL'}. Wall time {record['seconds']:.0f} s.",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=20)
    args = parser.parse_args()
    started = time.perf_counter()
    chain = kinematics.chain_from_urdf(
        (REPO / IIWA["urdf"]).read_text(), IIWA["base"], IIWA["flange"], source=str(REPO / IIWA["urdf"])
    )
    spec = files.read_yaml(SCENARIO)
    estimates = [zero_offset_estimates(chain, copy, seed) for copy, seed in scenario.copies(spec, args.copies)]
    names = estimates[0][0]
    z_paper = np.array([(b[1] - a[1]) / np.hypot(a[2], b[2]) for a, b in zip(estimates, estimates[1:])])
    z_sandwich = np.array([(b[1] - a[1]) / np.hypot(a[3], b[3]) for a, b in zip(estimates, estimates[1:])])
    record = {
        "date": date.today().isoformat(),
        "copies": args.copies,
        "parameters": names,
        "spread_paper": z_paper.std(axis=0).tolist(),
        "spread_sandwich": z_sandwich.std(axis=0).tolist(),
        "spread_paper_all": float(z_paper.std()),
        "spread_sandwich_all": float(z_sandwich.std()),
        "seconds": time.perf_counter() - started,
    }
    publish(RESULTS, "discrepancy", record, markdown(record), REPO / "docs" / "validation.md")


if __name__ == "__main__":
    main()
