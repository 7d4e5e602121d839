"""The calibrated URDFs against simulated truths at tools off the marker: paper.urdf, loop.urdf,
rigid.urdf and ik.urdf (`evaluation.rigid_urdf`, `calibration.exports`), each loaded alone by
`kinematics.chain_from_urdf`, beside the nominal chain and the loop-closed model, at the flange, a
tool 150 mm out along the flange's z axis and one at (100, 0, 100) mm; and `remaster predict --tcp`'s
per-command 95 % bound at those tools against the true error.

Cases: an iiwa simulated from data/simulation/kuka-compliance.yaml's set-up (laser tracker, joint 3
held) with (a) rigid link errors (`truth/link_errors`, 0.5 mm and 0.5 mrad per axis of every fixed
transform, written by the simulator's own code), (b) the scenario's joint compliance and payload,
(c) cyclic transmission errors of joints 2 and 4; smaller than the bundled campaigns for time
(`--optimization`, `--validation` configurations), one campaign per seed (`--seeds`). Each is
calibrated by `api.calibrate` with config.yaml's settings (its accuracy draws and configurations cut
to `api.truth.Probe`'s) and its URDFs made by the functions the calibrated stage calls
(`exports.calibrated_stage`, `rigid_urdf.rigid_urdf_fit`, `exports.calibrated_urdf`).

Where: `--configurations` random configurations inside the measured joint ranges
(`workspace.fit_domain(...).configurations`, as `api.truth.check` draws them). Frame: a calibration
is determined only up to its registration (joint 1's zero-offset against the base's rotation, the
base's position against the tracker's), so every model is compared in the frame it declares: its
tool points are taken into the tracker's frame through its own model's fitted registration
(`CalibratedRobot.in_frame`: paper.urdf and the nominal chain through the zero-offset model's,
loop.urdf, rigid.urdf and ik.urdf through the loop model's, as rigid.urdf and ik.urdf were fitted
in the loop model's robot frame), and the truth's through the true tracker pose
(`simulation.true_sensor_positions` with the marker replaced by the tool point and no marker error).
A distance there is the distance in the true robot's base frame (the tracker has no scale error
here). No alignment is fitted to the truth. The distance from the loop model is in its robot frame
(as `rigid_urdf` scores it): the loop model's tool point is `Calibration.robot('loop', tcp)` (its
marker offset and residual GP, measured at the marker, not applied to a tool).

Targets (printed, not tuned to): every URDF's median distance from the truth at most paper.urdf's at
every tool, except loop.urdf where the loop added an effect no URDF holds (its zero-offsets were
fitted with that effect beside them: rigid_urdf's module docstring); rigid.urdf the nearest URDF to
the loop model (median) at every tool; `predict --tcp` outside its 95 % bound at most 10 % of the
commands at every tool.

Writes benchmarks/results/urdf_tools.json and .md and the table into docs/validation.md between its
bench_urdf_tools markers. From the repository root:
    nice .venv/bin/python benchmarks/bench_urdf_tools.py [--seeds 1 2] [--cases links compliance cyclic]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import publish  # noqa: E402
from benchmarks.truth_claims import REPO  # noqa: E402
from remaster import api, configuration, files, identity, spatial  # noqa: E402
from remaster.api.truth import simulated_campaign  # noqa: E402
from remaster.calibration import exports  # noqa: E402
from remaster.calibration.prediction import loop_calibration, paper_calibration  # noqa: E402
from remaster.campaigns import scenario  # noqa: E402
from remaster.campaigns.arm_kinds import IIWA  # noqa: E402
from remaster.campaigns.simulation import true_sensor_positions  # noqa: E402
from remaster.evaluation import rigid_urdf, workspace  # noqa: E402
from remaster.robot import kinematics  # noqa: E402

SCENARIO = REPO / "data" / "simulation" / "kuka-compliance.yaml"
SENSOR = "laser_tracker"
RESULTS = REPO / "benchmarks" / "results"
OFFSETS_DEG = [0.35, -0.21, 0.12, 0.18, -0.27, 0.09, 0.62]
CYCLIC = {  # as tests/inference/test_gp_loop_candidate.py
    "amplitude_deg": [0, 0.02, 0, 0.015, 0, 0, 0],
    "cycles_per_turn": [1, 2, 1, 3, 1, 1, 1],
    "phase_deg": [0, 30, 0, -60, 0, 0, 0],
}
CASES = ("links", "compliance", "cyclic")
TOOLS = {"flange": (0.0, 0.0, 0.0), "150 mm out": (0.0, 0.0, 0.15), "(100, 0, 100) mm": (0.1, 0.0, 0.1)}
URDFS = ("paper.urdf", "loop.urdf", "rigid.urdf", "ik.urdf")
DRAWS = 1000  # posterior draws per bound, and the workspace claims' (api.truth.Probe's)
TIE = 1e-3  # mm: rigid.urdf counts as the nearest to the loop model within this of the nearest
OUTSIDE = 0.10  # predict --tcp: at most this share of commands outside the 95 % bound
URDF_HOLDS = ("link_geometry", "marker_offset")  # the loop's effects a URDF (or the user's tool) holds


def case_spec(case: str, seed: int, optimization: int, validation: int) -> dict:
    """The scenario of one case and seed: kuka-compliance's set-up with its truth replaced."""
    spec = files.read_yaml(SCENARIO)
    spec["name"] = f"urdf-tools-{case}-{seed}"
    spec["seed"] = int(spec["seed"]) + seed
    spec["plan"]["sets"] = {
        "optimization": {"poses": max(4, optimization // 5), "configurations": optimization},
        "validation": {"poses": max(2, validation // 5), "configurations": validation},
    }
    if case == "links":
        spec["truth"] = {
            "zero_offsets_deg": OFFSETS_DEG,
            "link_errors": {"translation_std": 5e-4, "rotation_std": 5e-4, "seed": seed},
        }
    elif case == "cyclic":
        spec["truth"] = {"zero_offsets_deg": OFFSETS_DEG, "cyclic_error": CYCLIC}
    elif case != "compliance":
        raise ValueError(f"unknown case {case!r}")
    return spec


def urdf_texts(calibration, seed: int) -> tuple[dict[str, str], dict]:
    """({file: URDF text} as the calibrated stage writes them (`handover.calibrated_outputs_stage`),
    rigid_urdf's own distances from the loop model at its default tools)."""
    campaign, results = calibration.campaign, calibration.results()
    summary, report = results["summary"], results["loop"]
    made = exports.calibrated_stage(campaign, SENSOR, summary, report)
    rigid = rigid_urdf.rigid_urdf_fit(campaign, SENSOR, paper_calibration(summary), loop_calibration(report), seed)
    return {
        "paper.urdf": made.paper_urdf,
        "loop.urdf": made.loop_urdf,
        "rigid.urdf": exports.calibrated_urdf(campaign.chain, rigid.values)[0],
        "ik.urdf": exports.calibrated_urdf(campaign.chain, rigid.ik_values)[0],
    }, rigid.at_tools


def flange_poses(text: str, q) -> np.ndarray:
    chain = kinematics.chain_from_urdf(text, IIWA["base"], IIWA["flange"], source="calibrated URDF")
    return kinematics.ForwardKinematics(chain, q).flange_poses()


def stats(d_mm) -> dict:
    return {"median_mm": float(np.median(d_mm)), "p95_mm": float(np.quantile(d_mm, 0.95))}


def one_run(case: str, seed: int, args, chain, settings) -> dict:
    """Every model's distances at every tool for one simulated campaign."""
    started = time.perf_counter()
    campaign, truth = simulated_campaign(case_spec(case, seed, args.optimization, args.validation), chain, REPO)
    calibration = api.calibrate(campaign, SENSOR, settings, seed=seed)
    data = campaign.sensors[SENSOR]
    q = workspace.fit_domain(campaign.chain, data, calibration.laplace.outlier_rows).configurations(
        identity.robot_identity(campaign), args.configurations, seed
    )
    true_robot = scenario.robot_from_truth(truth)
    device = scenario.sensor_from_truth(truth, SENSOR, data.marker)
    texts, own_report = urdf_texts(calibration, seed)
    flanges = {name: flange_poses(text, q) for name, text in texts.items()}
    flanges["nominal"] = kinematics.ForwardKinematics(campaign.chain, q).flange_poses()
    frame_of = {"paper.urdf": "paper", "nominal": "paper"} | {n: "loop" for n in URDFS[1:]}
    out = {"case": case, "seed": seed, "effects": list(calibration.effects), "tools": {}}
    for tool, point in TOOLS.items():
        point = np.asarray(point)
        tool_device = replace(device, marker=point, marker_error=np.zeros(3))
        true = true_sensor_positions(campaign.chain, true_robot, tool_device, q, np.zeros(len(q)))
        robots = {m: calibration.robot(m, point) for m in ("paper", "loop")}
        loop_robot_frame = robots["loop"].robot_points(q)
        row = {"from_truth": {}, "from_loop": {}}
        for name, flange in flanges.items():
            at = rigid_urdf.tool_positions(flange, point)
            if name == "nominal":  # the initial registration alone (no model's corrections)
                in_sensor = spatial.transform_points(robots["paper"].t_nr, at)
            else:
                in_sensor = robots[frame_of[name]].in_frame(at, "sensor")
            row["from_truth"][name] = stats(np.linalg.norm(in_sensor - true, axis=1) / 1e-3)
            row["from_loop"][name] = stats(np.linalg.norm(at - loop_robot_frame, axis=1) / 1e-3)
        predicted = api.predict(calibration, q, frame="sensor", tcp=point, draws=DRAWS, seed=seed)
        error = np.linalg.norm(predicted[["x", "y", "z"]].to_numpy() - true, axis=1) / 1e-3
        row["from_truth"]["loop model"] = stats(error)
        row["outside_bound"] = float(np.mean(error > predicted["bound95_mm"].to_numpy()))
        row["bound_median_mm"] = float(np.median(predicted["bound95_mm"]))
        out["tools"][tool] = row
    # rigid_urdf's own distances from the loop model at its default tools (its scoring configurations)
    out["rigid_urdf_report"] = own_report
    out["seconds"] = time.perf_counter() - started
    print(f"{case} seed {seed}: {out['effects']} {out['seconds']:.0f} s", flush=True)
    return out


def pooled(runs: list[dict], case: str, tool: str, where: str, name: str, key: str) -> float:
    """The mean over the seeds of one statistic."""
    return float(np.mean([r["tools"][tool][where][name][key] for r in runs if r["case"] == case]))


def targets(record: dict) -> dict:
    """Each target per case and tool (medians averaged over the seeds)."""
    runs, out = record["runs"], {"no_farther_than_paper": [], "rigid_nearest_loop": [], "predict_tcp": []}
    for case in record["cases"]:
        case_runs = [r for r in runs if r["case"] == case]
        unheld = sorted({e for r in case_runs for e in r["effects"] if e not in URDF_HOLDS})
        for tool in TOOLS:
            paper = pooled(runs, case, tool, "from_truth", "paper.urdf", "median_mm")
            for name in URDFS[1:]:
                value = pooled(runs, case, tool, "from_truth", name, "median_mm")
                exempt = name == "loop.urdf" and bool(unheld)
                out["no_farther_than_paper"].append(
                    {"case": case, "tool": tool, "urdf": name, "median_mm": value, "paper_mm": paper,
                     "pass": value <= paper, "exempt": ", ".join(unheld) if exempt else ""}
                )  # fmt: skip
            near = {n: pooled(runs, case, tool, "from_loop", n, "median_mm") for n in URDFS}
            nearest = min(near, key=near.get)  # a tie within TIE (loop.urdf is the loop model when it adds links alone)
            out["rigid_nearest_loop"].append(
                {"case": case, "tool": tool, "nearest": nearest, "pass": near["rigid.urdf"] <= near[nearest] + TIE}
            )
            share = float(np.mean([r["tools"][tool]["outside_bound"] for r in case_runs]))
            out["predict_tcp"].append({"case": case, "tool": tool, "outside": share, "pass": share <= OUTSIDE})
    return out


def markdown(record: dict) -> str:
    runs, checks = record["runs"], record["targets"]
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_urdf_tools.py`: an iiwa with (links) rigid link errors "
        "0.5 mm / 0.5 mrad, (compliance) kuka-compliance's joint compliance and payload, (cyclic) transmission "
        f"errors of q2 and q4; laser tracker, {record['optimization']} optimization and {record['validation']} "
        f"validation configurations, seeds {', '.join(map(str, record['seeds']))}; {record['configurations']} "
        "random configurations inside the measured joint ranges; each model in the tracker's frame through its "
        "own fitted registration. Distance (mm), median / p95, averaged over the seeds.",
        "",
        "| case | effects the loop added | tool | nominal | paper.urdf | loop.urdf | rigid.urdf | ik.urdf | loop model "
        "| from the loop model: paper / loop / rigid / ik (median) | predict --tcp outside its bound | its median "
        "bound (mm) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for case in record["cases"]:
        case_runs = [r for r in runs if r["case"] == case]
        effects = "; ".join(sorted({", ".join(r["effects"]) or "none" for r in case_runs}))
        for tool in TOOLS:
            from_loop = " / ".join(f"{pooled(runs, case, tool, 'from_loop', n, 'median_mm'):.3f}" for n in URDFS)
            outside = np.mean([r["tools"][tool]["outside_bound"] for r in case_runs])
            bound = np.mean([r["tools"][tool]["bound_median_mm"] for r in case_runs])
            names = ["nominal", *URDFS, "loop model"]
            lines.append(
                f"| {case} | {effects} | {tool} | {' | '.join(_cell(runs, case, tool, n) for n in names)} | {from_loop} "
                f"| {100 * outside:.0f} % | {bound:.3f} |"
            )
    farther = [c for c in checks["no_farther_than_paper"] if not c["pass"]]
    missed = [c for c in farther if not c["exempt"]]
    exempt = [c for c in farther if c["exempt"]]
    not_nearest = [c for c in checks["rigid_nearest_loop"] if not c["pass"]]
    tcp = checks["predict_tcp"]
    worst = max(tcp, key=lambda c: c["outside"])
    lines += [
        "",
        "Each URDF no farther from the truth than paper.urdf (median): "
        + ("pass" if not missed else "FAIL at " + "; ".join(_farther(c) for c in missed))
        + ("" if not exempt else " (exempt, the loop added what no URDF holds: " + "; ".join(_farther(c) for c in exempt) + ")")
        + ". rigid.urdf the nearest to the loop model at every tool: "
        + ("pass" if not not_nearest else "FAIL at " + "; ".join(f"{c['case']} {c['tool']} ({c['nearest']})" for c in not_nearest))
        + f". predict --tcp outside its 95 % bound at most {100 * OUTSIDE:.0f} %: "
        + ("pass" if all(c["pass"] for c in tcp) else "FAIL")
        + f" (largest {100 * worst['outside']:.0f} %, {worst['case']} at {worst['tool']}). "
        + f"Wall time {record['seconds']:.0f} s.",
    ]  # fmt: skip
    return "\n".join(lines)


def _cell(runs: list[dict], case: str, tool: str, name: str) -> str:
    """'median / p95' of one model's distance from the truth (mm, means over the seeds)."""
    m = pooled(runs, case, tool, "from_truth", name, "median_mm")
    return f"{m:.3f} / {pooled(runs, case, tool, 'from_truth', name, 'p95_mm'):.3f}"


def _farther(c: dict) -> str:
    return f"{c['urdf']} {c['case']} {c['tool']} {c['median_mm']:.3f} against {c['paper_mm']:.3f} mm"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    parser.add_argument("--optimization", type=int, default=80)
    parser.add_argument("--validation", type=int, default=20)
    parser.add_argument("--configurations", type=int, default=300)
    args = parser.parse_args()
    started = time.perf_counter()
    chain = kinematics.chain_from_urdf(
        (REPO / IIWA["urdf"]).read_text(), IIWA["base"], IIWA["flange"], source=str(REPO / IIWA["urdf"])
    )
    settings = configuration.settings(files.read_yaml(REPO / "config.yaml"))
    settings["accuracy"] = {**settings["accuracy"], "draws": DRAWS, "random_configurations": args.configurations}
    runs = [one_run(case, seed, args, chain, settings) for case in args.cases for seed in args.seeds]
    record = {
        "date": date.today().isoformat(),
        "cases": args.cases,
        "seeds": args.seeds,
        "optimization": args.optimization,
        "validation": args.validation,
        "configurations": args.configurations,
        "tools_m": TOOLS,
        "runs": runs,
        "seconds": time.perf_counter() - started,
    }
    record["targets"] = targets(record)
    publish(RESULTS, "urdf_tools", record, markdown(record), REPO / "docs" / "validation.md")


if __name__ == "__main__":
    main()
