"""The real UR10's four campaigns: does a calibration carry over to another series of the same arm?

One UR10 measured by a laser tracker in four series over eight months (/work/shared/real/README.md:
A grid, B chosen joint configurations, C random poses, D ISO cubes with one tool orientation). Each
series given as a source is calibrated through the Python API (`api.calibrate`: registration, the
zero-offset fit, the loop closure); then every series it is paired with is predicted with the
source's kinematics frozen and the target's registration refitted on the target's optimization rows
(`comparing.transfer.transfer_errors`), the RMS taken over the target's validation rows
(`transfer_pairs`: the comparison bench_transfer.py makes on simulated campaigns). The models on
every pair, the same rows for each:

- nominal: the robot description unchanged;
- zero-offset (the paper's model): the Laplace fit's zero-offsets;
- loop-closed: the loop closure's model (its parametric effects; the residual GP is not transferred);
- complete-model least squares: zero-offsets, every link's six parameters, the marker offset and
  joint compliance, fitted flat on the source's optimization rows
  (`truth_claims.least_squares_validation`, the other benchmarks' baseline); beside it, shown but
  not a target, the same without the compliance ("rigid": zero-offsets, links, marker).

Targets: every transfer of the loop-closed model within 1.1x the least squares' on the same pair and
below the nominal model's; from D (one tool orientation leaves least squares ill-posed) within 1.1x
the better of least squares and the nominal model. A pair with source = target is the source's own
validation (shown, not held to the targets).

The settings are the schema's defaults with the residual GP not tried (it is not transferred) and
fewer draws for the workspace claims and the acceptance test (not used here). `--subsample N` keeps N
of a source's optimization rows, chosen by one generator from `--seed` drawn in the sources' order, so a
source's rows depend on the sources run before it (A has 8,338, C 1,941: the default keeps 1,500 of
them to hold a calibration to minutes); the targets keep every row. Writes
benchmarks/results/ur10_transfer.json and .md and the table into docs/validation.md between its
bench_ur10_transfer markers (`--rewrite`: the tables again from the JSON, nothing recomputed). From the
repository root:
    .venv/bin/python benchmarks/bench_ur10_transfer.py [--data ../shared/real] [--pairs a:b,a:c,...]
        [--subsample N] [--seed S] [--rewrite]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks import transfer_pairs  # noqa: E402
from benchmarks.doc_sections import publish  # noqa: E402
from benchmarks.transfer_pairs import WITHIN, models_of, pair_rms, verdict  # noqa: E402
from benchmarks.truth_claims import REPO  # noqa: E402
from remaster import api  # noqa: E402
from remaster.calibration import prediction  # noqa: E402
from remaster.inference import fit  # noqa: E402
from remaster.inference.laplace_report import LaplaceReport  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
SERIES = {
    "a": "landgraf-ur10-a-grid",
    "b": "landgraf-ur10-b-joint-configurations",
    "c": "landgraf-ur10-c-random",
    "d": "landgraf-ur10-d-iso-cubes",
}
SENSOR = "laser_tracker"
ONE_ORIENTATION = ("d",)  # least squares ill-posed from these: held to the better of it and the nominal model
REDUCED = {
    "loop_closure": {"residual_gp": {"enabled": False}},
    "accuracy": {"draws": 200, "random_configurations": 200},
    "acceptance": {"draws": 200},
}


def subsampled(campaign, keep: int, rng: np.random.Generator):
    """The campaign with `keep` of its optimization rows (chosen by rng), every validation row; the
    campaign unchanged when it has no more than `keep` (keep 0: every row)."""
    data = campaign.sensors[SENSOR]
    table = data.table
    optimization = np.flatnonzero(table["set"].to_numpy() == "optimization")
    if keep <= 0 or len(optimization) <= keep:
        return campaign
    kept = np.sort(
        np.concatenate([rng.choice(optimization, keep, replace=False), np.flatnonzero(table["set"] != "optimization")])
    )
    data = replace(data, table=table.iloc[kept].reset_index(drop=True))
    return replace(campaign, sensors={**campaign.sensors, SENSOR: data})


def target_of(campaign) -> prediction.Calibrated:
    """A series as a transfer's target: its readings and the rows its own zero-offset fit flagged as gross errors."""
    registered = fit.registration_stage(campaign, SENSOR)
    laplace = LaplaceReport.of(fit.laplace_stage(campaign, SENSOR, registered, api.settings()["outliers"]))
    return transfer_pairs.target_of(campaign, SENSOR, laplace.outlier_rows)


def source_of(campaign, seed: int) -> dict:
    """A series calibrated (`api.calibrate`, REDUCED settings) with least squares beside: its models
    (`transfer_pairs.models_of`)."""
    started = time.perf_counter()
    calibration = api.calibrate(campaign, SENSOR, api.settings(REDUCED), seed=seed)
    seconds = time.perf_counter() - started
    return {
        **models_of(calibration, campaign.name),
        "effects": list(calibration.effects),
        "optimization_rows": int(np.sum(campaign.sensors[SENSOR].table["set"] == "optimization")),
        "calibration_seconds": seconds,
    }


def markdown(record: dict) -> str:
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_ur10_transfer.py` on the real UR10's series "
        f"({', '.join(f'{k.upper()} {v}' for k, v in SERIES.items())}): each source calibrated "
        f"on {record['subsample'] or 'all'} of its optimization rows at most (seeded choice, seed {record['seed']}), "
        f"joint encoders {record.get('joint_encoders', 'as declared')} (robot/joint_encoders: the joint scale's prior), "
        "each target's registration and marker refitted on its optimization rows with the source's kinematics frozen, "
        "RMS over its validation rows (mm). Least squares: zero-offsets, every link, the marker offset and "
        "joint compliance, flat; rigid: the same without the compliance (shown, not a target). Baseline: least "
        "squares, or from D the better of it and the nominal model.",
        "",
        "| calibrated on | predicting | validation rows | nominal | zero-offset | loop-closed | least squares | "
        "least squares, rigid | loop / baseline | loop below nominal |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in record["pairs"]:
        own = r["source"] == r["target"]
        lines.append(
            f"| {r['source'].upper()} | {r['target'].upper()}{' (own)' if own else ''} | {r['count']} | "
            f"{r['nominal_rms_mm']:.3f} | {r['paper_rms_mm']:.3f} | {r['loop_rms_mm']:.3f} | "
            f"{r['least_squares_rms_mm']:.3f} | {r.get('least_squares_rigid_rms_mm', float('nan')):.3f} | "
            f"{r['loop_over_baseline']:.2f} | "
            f"{'yes' if r['below_nominal'] else '**no**'} |"
        )
    lines += [
        "",
        "| series | optimization rows used | effects the loop added | least-squares parameters | "
        "calibration (s) | least squares (s) |",
        "|---|---|---|---|---|---|",
    ]
    for key, s in record["sources"].items():
        lines.append(
            f"| {key.upper()} | {s['optimization_rows']} | {', '.join(s['effects']) or 'none'} | "
            f"{s['least_squares_parameters']} | {s['calibration_seconds']:.0f} | {s['least_squares_seconds']:.0f} |"
        )
    transfers = [r for r in record["pairs"] if r["source"] != r["target"]]
    within = sum(r["within_baseline"] for r in transfers)
    below = sum(r["below_nominal"] for r in transfers)
    missed = [r for r in transfers if not (r["within_baseline"] and r["below_nominal"])]
    squares_worse = sum(r["least_squares_rms_mm"] > r["nominal_rms_mm"] for r in transfers)
    paper_worse = sum(r["paper_rms_mm"] > r["nominal_rms_mm"] for r in transfers)
    rigid_better = sum(r["loop_rms_mm"] > r.get("least_squares_rigid_rms_mm", np.inf) for r in transfers)
    lines += [
        "",
        f"Transfers within {WITHIN}x the baseline: {within} of {len(transfers)}; below the nominal model: "
        f"{below} of {len(transfers)} (target: all of both)"
        + (
            "; missed: "
            + ", ".join(
                f"{r['source'].upper()} -> {r['target'].upper()} ({r['loop_over_baseline']:.2f}x the baseline)"
                for r in missed
            )
            if missed
            else ""
        )
        + f". Least squares farther than the nominal model: {squares_worse} of {len(transfers)} transfers; the "
        f"zero-offset model: {paper_worse} of {len(transfers)}. Rigid least squares nearer than the loop-closed "
        f"model: {rigid_better} of {len(transfers)}. Wall time {record['seconds']:.0f} s.",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared" / "real", help="the folder of the series")
    parser.add_argument(
        "--pairs",
        default=",".join(f"{s}:{t}" for s in SERIES for t in SERIES),
        help="source:target pairs, comma-separated (a:a is the source's own validation)",
    )
    parser.add_argument("--subsample", type=int, default=1500, help="optimization rows a source keeps (0: all)")
    parser.add_argument("--seed", type=int, default=20181113)
    parser.add_argument(
        "--joint-encoders",
        default="output",
        help="robot/joint_encoders for every series (a UR reads its joints at the output; '' keeps what the series "
        "declare, which is nothing: the motor's prior)",
    )
    parser.add_argument("--rewrite", action="store_true", help="the tables again from results/ur10_transfer.json")
    args = parser.parse_args()
    if args.rewrite:
        record = json.loads((RESULTS / "ur10_transfer.json").read_text(encoding="utf-8"))
        publish(RESULTS, "ur10_transfer", record, markdown(record), REPO / "docs" / "validation.md")
        return
    started = time.perf_counter()
    pairs = [tuple(p.strip().lower().split(":")) for p in args.pairs.split(",") if p.strip()]
    unknown = {k for p in pairs for k in p} - set(SERIES)
    if unknown or any(len(p) != 2 for p in pairs):
        parser.error(f"pairs are source:target of {', '.join(SERIES)}")
    campaigns = {k: api.calibration.as_campaign(args.data / SERIES[k]) for k in sorted({k for p in pairs for k in p})}
    if args.joint_encoders:  # what a user of a UR declares: it reads each joint at its output
        campaigns = {
            k: replace(c, robot={**c.robot, "joint_encoders": args.joint_encoders}) for k, c in campaigns.items()
        }
    rng = np.random.default_rng(args.seed)
    sources, targets, rows = {}, {}, []
    for key in sorted({s for s, _ in pairs}):
        sources[key] = source_of(subsampled(campaigns[key], args.subsample, rng), args.seed)
        print(f"{key}: {sources[key]['effects']} in {sources[key]['calibration_seconds']:.0f} s", flush=True)
    for source, target in pairs:
        if target not in targets:
            targets[target] = target_of(campaigns[target])
        row = {"source": source, "target": target, **pair_rms(sources[source]["models"], targets[target])}
        rows.append({**row, **verdict(row, source in ONE_ORIENTATION)})
    record = {
        "date": date.today().isoformat(),
        "data": str(args.data),
        "subsample": args.subsample,
        "seed": args.seed,
        "joint_encoders": args.joint_encoders or "as declared",
        "within": WITHIN,
        "sources": {k: {n: v for n, v in s.items() if n != "models"} for k, s in sources.items()},
        "pairs": rows,
        "seconds": time.perf_counter() - started,
    }
    publish(RESULTS, "ur10_transfer", record, markdown(record), REPO / "docs" / "validation.md")


if __name__ == "__main__":
    main()
