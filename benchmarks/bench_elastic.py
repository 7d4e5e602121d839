"""An elastic arm whose robot description has no masses: does the loop closure still find its sag?

The bundled `kuka-compliance` campaign (simulated: zero-offsets and joint compliance under gravity,
the true torques from the iiwa URDF's masses and a 2.5 kg payload) goes through the pipeline's own
stages in-process (registration, the paper's fit, the loop closure with config.yaml's settings, its
MCMC refit left out) four times:

- `masses`: as bundled, the URDF with its inertials;
- `regressor`: the same URDF with every `<inertial>` removed: the arm's weight is remaster's gravity
  regressor (1 kg and its first moments at each moving joint frame, `robot.gravity.gravity_regressor`);
- `dh`: the robot given as the iiwa's DH table alone (`arm_kinds.IIWA_DH`, no masses; its frames,
  hence the regressor's, are the DH table's);
- `payload alone`: the massless URDF, the torques from the payload alone (the regressor switched
  off: what remaster did before it).

Beside each, the baseline a calibration engineer would fit on the same torques: least squares of the
complete model with compliance (zero-offsets, every link's six parameters, the marker offset, joint
compliance, no priors; `truth_claims.least_squares_validation`). Per run: the effects the loop
added, whether it closed, and the validation set's RMS distance and RMS per axis (mm) of both, never
used for a choice. Writes benchmarks/results/elastic.json and elastic.md, and the table into docs/validation.md between its bench_elastic markers. From the repository root:
    .venv/bin/python benchmarks/bench_elastic.py
"""

from __future__ import annotations

import re
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from datetime import date
from pathlib import Path

import numpy as np
from snakemake.utils import validate

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import publish  # noqa: E402
from benchmarks.truth_claims import REPO, least_squares_validation  # noqa: E402
from remaster import files  # noqa: E402
from remaster.campaigns import folders  # noqa: E402
from remaster.campaigns.arm_kinds import IIWA_DH  # noqa: E402
from remaster.inference import blocks, fit, parameter_blocks  # noqa: E402
from remaster.inference.laplace_report import LaplaceReport  # noqa: E402
from remaster.loop import loop_closure  # noqa: E402
from remaster.loop.settings import settings_from  # noqa: E402
from remaster.robot import gravity  # noqa: E402

CAMPAIGN, SENSOR = "kuka-compliance", "laser_tracker"
RESULTS = REPO / "benchmarks" / "results"
MODES = {
    "masses": "the URDF's masses",
    "regressor": "URDF without masses: gravity regressor",
    "dh": "DH table (no masses): gravity regressor",
    "payload": "URDF without masses: payload alone",
}
COMPLETE = ("link_geometry", "marker_offset", "joint_compliance")
WITHIN = 1.15  # the loop's validation RMS on a massless arm over least squares with compliance's


def campaign_copy(root: Path, mode: str):
    """The bundled campaign in root/<mode>/, its URDF beside it, without inertials unless `masses`."""
    folder = root / mode / CAMPAIGN
    shutil.copytree(REPO / "data" / "raw" / CAMPAIGN, folder)
    meta = files.read_yaml(folder / "campaign.yaml")
    urdf = (REPO / meta["robot"]["urdf"]).read_text(encoding="utf-8")
    if mode != "masses":
        urdf = re.sub(r"<inertial>.*?</inertial>", "", urdf, flags=re.S)
    (folder / "robot.urdf").write_text(urdf, encoding="utf-8")
    meta["robot"]["urdf"] = "robot.urdf"
    if mode == "dh":
        meta["robot"] = {"serial": meta["robot"]["serial"], "dh": {"convention": "standard", "rows": IIWA_DH}}
    files.write_yaml(folder / "campaign.yaml", meta)
    return folders.read_campaign(folder, repo_root=REPO)


def run(root: Path, mode: str) -> dict:
    """One loop closure of the campaign under `mode` (module docstring)."""
    config = files.read_yaml(REPO / "config.yaml")
    validate(config, str(REPO / "workflow" / "schemas" / "config.schema.yaml"))  # the schema's defaults
    campaign = campaign_copy(root, mode)
    without_mass = gravity.without_mass
    if mode == "payload":  # no regressor: the payload's torques alone, one compliance per joint
        gravity.without_mass = blocks.without_mass = parameter_blocks.without_mass = lambda chain: False
    try:
        start = time.perf_counter()
        registered = fit.registration_stage(campaign, SENSOR)
        laplace = LaplaceReport.of(fit.laplace_stage(campaign, SENSOR, registered, config["outliers"]))
        settings = settings_from(
            config["loop_closure"], config["priors"], config["fit"]["cross_check"], config["outliers"]
        )
        result = loop_closure.loop_closure_stage(
            campaign, SENSOR, registered, laplace, np.random.default_rng(config["seed"]), replace(settings, mcmc=None)
        )
        seconds = time.perf_counter() - start
        least_squares = least_squares_validation(campaign, SENSOR, registered, laplace, settings, COMPLETE)
    finally:
        gravity.without_mass = blocks.without_mass = parameter_blocks.without_mass = without_mass
    report = result.report.to_json()
    after = report["after"]["validation"]
    return {
        "mode": mode,
        "torques": MODES[mode],
        "effects_added": report["effects_added"],
        "closure": report["closure"].get("verdict", ""),
        "validation_rmse_mm": after["rmse_mm"],
        "validation_rms_per_axis_mm": after["rms_per_axis_mm"],
        "least_squares_validation_rmse_mm": least_squares["rmse_mm"],
        "least_squares_parameters": least_squares["parameters"],
        "seconds": seconds,
    }


def markdown(record: dict) -> str:
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_elastic.py` on `{CAMPAIGN}` ({SENSOR}):",
        "",
        "| robot and gravity torques | effects added | loop | validation RMS (mm): loop | RMS per axis | "
        "least squares with compliance (same torques) | loop / least squares |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in record["runs"]:
        lines.append(
            f"| {r['torques']} | {', '.join(r['effects_added']) or 'none'} | {r['closure']} | "
            f"{r['validation_rmse_mm']:.4f} | {r['validation_rms_per_axis_mm']:.4f} | "
            f"{r['least_squares_validation_rmse_mm']:.4f} ({r['least_squares_parameters']} parameters) | "
            f"{r['validation_rmse_mm'] / r['least_squares_validation_rmse_mm']:.2f} |"
        )
    by = {r["mode"]: r for r in record["runs"]}
    loop = {mode: r["validation_rmse_mm"] for mode, r in by.items()}
    best = by["masses"]["least_squares_validation_rmse_mm"]  # the true torques' shape: the strongest baseline
    verdict = "within" if loop["dh"] <= WITHIN * best else "not within"
    lines += [
        "",
        f"Without masses, the gravity regressor validates at {loop['regressor'] / loop['masses']:.2f} x the error the same "
        f"loop reaches with the URDF's masses; the payload alone at {loop['payload'] / loop['masses']:.2f} x. "
        f"The arm given as a DH table validates at {loop['dh'] / best:.2f} x least squares with compliance on "
        f"the URDF's masses ({verdict} {WITHIN:.2f} x).",
    ]
    return "\n".join(lines)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        runs = [run(Path(tmp), mode) for mode in MODES]
    record = {"date": date.today().isoformat(), "runs": runs}
    publish(RESULTS, "elastic", record, markdown(record), REPO / "docs" / "validation.md")


if __name__ == "__main__":
    main()
