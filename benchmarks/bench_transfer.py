"""Calibrations that transfer: does a calibration predict another campaign of the same robot as well
as complete-model least squares does, within the bound it states there?

Simulated campaigns shaped like the real transfers that failed, of truths no block of the loop
closure expresses exactly (the same true robot for every campaign of a seed, unless the truth is said
to change):

- designs (the iiwa): every joint turning (Latin-hypercube poses, joint 3 drawn per pose); random
  configurations in ONE region of joint space (joints 1, 2 and 4 within a narrow range each); ISO
  9283 cubes with ONE tool orientation; every joint again with the marker remounted (the reflector
  moved on the tool plate, the robot unchanged);
- designs (a UR5 given by its DH table, joints without limits as a UR's +-2 pi: the iiwa's limits are
  below pi): random configurations with joint 1 in one range, and the same with joint 1 ONE TURN up;
  both arms read each joint at its output (campaign.yaml robot/joint_encoders: output, as the bundled
  iiwa and UR5 campaigns declare);
- truths: zero-offsets plus a smooth nonlinear joint error of joints 1 and 2 (a sine of 0.3-0.35
  cycles per turn: no harmonic of the turn, which a joint scale imitates over one range); or backlash
  (half the play of joints 2-4, by the direction each joint approached the reading from); or, on
  the iiwa measured twice with every joint turning, thermal growth (every link 0.03 % longer in the
  second campaign: a truth that DID change).

Each campaign goes through the pipeline's stages in-process (`truth_claims.check`) and is held on
every other campaign of its group (`transfer_pairs`: the source's kinematics frozen, the target's
registration and marker refitted on its optimization rows, RMS over its validation rows) beside complete-model
least squares fitted on the source, the zero-offset model and the nominal model; with the share of
the target's validation commands where the true error of the source's `remaster predict` (its own
sensor set-up) exceeds its per-command 95 % bound. Every pair of campaigns is also compared by
`remaster.comparing.comparison` (zero-offset drift, loop-parameter drift of the robot's blocks).

Targets (printed, not tuned to): on every pair the loop-closed model within 1.1x least squares, and
no farther than the zero-offset or the nominal model; drift flagged only where the truth changed.

Writes benchmarks/results/transfer.json and transfer.md and the table into docs/validation.md between
its bench_transfer markers. From the repository root:
    .venv/bin/python benchmarks/bench_transfer.py [--seeds N] [--first SEED] [--n-random N] [--draws D]
        [--groups arm:truth,...] [--rewrite]
"""

from __future__ import annotations

import argparse
import copy
import datetime as dt
import json
import math
import sys
import time
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import publish  # noqa: E402
from benchmarks.transfer_pairs import SIGNIFICANT, WITHIN, models_of, pair_rms, target_of, verdict  # noqa: E402
from benchmarks.truth_claims import REPO, check  # noqa: E402
from remaster import api, files, identity  # noqa: E402
from remaster.campaigns import scenario  # noqa: E402
from remaster.campaigns.arm_kinds import (  # noqa: E402
    IIWA_OFFSETS_DEG,
    OPTIMIZATION,
    TRACKER,
    UR5_OFFSETS_DEG,
    VALIDATION,
    chain_of,
    iiwa_scenario,
    ur5_with_dh_errors,
)
from remaster.comparing import comparison  # noqa: E402
from remaster.inference import discrepancy  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
SENSOR = "laser_tracker"
MAX_OUTSIDE = 0.10
FIRST_DATE = dt.date(2024, 5, 6)


@dataclass(frozen=True)
class Design:
    """One campaign of a group: its plan and sensors (keys replacing the arm's scenario's) and what
    of the truth is this campaign's own (a truth that changed)."""

    plan: dict
    sensors: dict | None = None
    truth: dict = field(default_factory=dict)


RANDOM_SETS = {"optimization": {"configurations": OPTIMIZATION}, "validation": {"configurations": VALIDATION}}
REGION = {"q1": [-0.4, 0.4], "q2": [0.3, 0.9], "q4": [-1.6, -1.0]}  # rad, one region of the iiwa's joint space


def _cubes(angles_deg, radius: float, height: float) -> list[dict]:
    return [
        {"centre": [radius * math.cos(math.radians(a)), radius * math.sin(math.radians(a)), height], "edge": 0.2}
        for a in angles_deg
    ]


CUBES = {  # 5 points per cube, one tool orientation (kuka-cubes' workspace)
    "design": "iso9283_cubes",
    "tool_angle": 0.0,
    "q3": 0.0,
    "sets": {
        "optimization": {"cubes": _cubes([0, 120, 240], 0.35, 0.70)},
        "validation": {"cubes": _cubes([60, 180], 0.35, 0.68)},
    },
}
REMOUNTED = {"laser_tracker": {**TRACKER, "marker_error": [4.0e-4, -3.0e-4, 2.0e-4]}}  # m, the reflector moved
IIWA_DESIGNS = {
    "every joint": Design({"q3": "free"}),
    "one region": Design({"design": "random_joints", "joint_ranges": REGION, "sets": RANDOM_SETS}),
    "cubes, one orientation": Design(CUBES),
    "marker remounted": Design({"q3": "free"}, REMOUNTED),
}
UR_Q1 = (-2.0, -0.3)  # rad: a turn up stays within +-2 pi, the limits a campaign table may hold
UR_DESIGNS = {
    "q1 in one range": Design({"joint_ranges": {"q1": list(UR_Q1)}}),
    "q1 a turn up": Design({"joint_ranges": {"q1": [UR_Q1[0] + 2 * math.pi, UR_Q1[1] + 2 * math.pi]}}),
}
THERMAL = {"link_scale": 3.0e-4}  # every link 0.03 % longer
THERMAL_DESIGNS = {
    "every joint, cold": Design({"q3": "free"}),
    "every joint, warm": Design({"q3": "free"}, None, THERMAL),
}


def nonlinear_joints(n_joints: int) -> dict:
    """A smooth nonlinear error of joints 1 and 2 (0.05 and 0.04 deg amplitude, 0.35 and 0.30 cycles
    per turn): the simulator's cyclic error at a fraction of a cycle per turn, no harmonic of the turn."""
    terms = []
    for joint, amplitude, cycles, phase in ((0, 0.05, 0.35, 20.0), (1, 0.04, 0.30, -40.0)):
        term = {"amplitude_deg": [0.0] * n_joints, "cycles_per_turn": [1.0] * n_joints, "phase_deg": [0.0] * n_joints}
        term["amplitude_deg"][joint], term["cycles_per_turn"][joint], term["phase_deg"][joint] = (
            amplitude,
            cycles,
            phase,
        )
        terms.append(term)
    return {"cyclic_error": terms}


def backlash(n_joints: int) -> dict:
    """Half the play of joints 2, 3 and 4: 0.012 deg each way, by the direction of approach."""
    return {"backlash_deg": [0.012 if j in (1, 2, 3) else 0.0 for j in range(n_joints)]}


TRUTHS = {"nonlinear joint": nonlinear_joints, "backlash": backlash, "thermal growth": lambda n: {}}
GROUPS = {  # (arm, truth): its campaigns
    ("iiwa", "nonlinear joint"): IIWA_DESIGNS,
    ("iiwa", "backlash"): IIWA_DESIGNS,
    ("ur5", "nonlinear joint"): UR_DESIGNS,
    ("ur5", "backlash"): UR_DESIGNS,
    ("iiwa", "thermal growth"): THERMAL_DESIGNS,
}


def spec_of(arm: str, truth: str, design: str, seed: int) -> dict:
    """The scenario of one campaign: the group's k-th campaign simulated from seed + 1000 k, dated k days on."""
    designs = GROUPS[(arm, truth)]
    k = list(designs).index(design)
    chosen = designs[design]
    name = f"{arm}-{truth}-{design}-{seed}".replace(" ", "-").replace(",", "")
    if arm == "iiwa":
        spec = iiwa_scenario(name, seed=seed + 1000 * k, plan=chosen.plan, sensors=chosen.sensors)
        offsets = IIWA_OFFSETS_DEG
    else:
        spec = ur5_with_dh_errors(seed=seed + 1000 * k)
        spec["plan"] = {**spec["plan"], **copy.deepcopy(chosen.plan)}
        spec["sensors"] = copy.deepcopy(chosen.sensors) if chosen.sensors else spec["sensors"]
        offsets = UR5_OFFSETS_DEG
    n_joints = len(offsets)
    # both arms read each joint at its output, after the gear, as their bundled campaigns declare:
    # a joint scale is then an encoder's graduation (tens of ppm), not a gear ratio's error
    spec["robot"] = {**spec["robot"], "joint_encoders": "output"}
    spec["name"], spec["date"] = name, (FIRST_DATE + dt.timedelta(days=k)).isoformat()
    spec["truth"] = {"zero_offsets_deg": list(offsets), **TRUTHS[truth](n_joints), **chosen.truth}
    return spec


def validation_q(spec: dict) -> np.ndarray:
    """The validation commands (m, N) rad of one campaign (the simulator is deterministic in its seed)."""
    table = scenario.simulate(spec, chain_of(spec, REPO)).tables[SENSOR]
    rows = table[table["set"] == "validation"]
    return rows[[c for c in rows.columns if c.startswith("q") and c[1:].isdigit()]].to_numpy(float)


def as_compared(calibration):
    """The zero-offset model's summary as the workflow's comparison across campaigns reads it
    (`summary_discrepancy`): the fit's means with the pose-clustered sandwich stds, which carry
    what the model lacks (`discrepancy.discrepancy_stage`), from its summary at the mode."""
    summary = calibration.summary.copy()
    laplace = calibration.laplace
    summary.loc[list(laplace.names), "std"] = np.asarray(laplace.std, dtype=float)
    compared, _ = discrepancy.discrepancy_stage(
        calibration.campaign, calibration.sensor, calibration.registration, laplace, summary
    )
    return compared


def drift_of(first, second) -> dict:
    """What `remaster.comparing.comparison` says between two calibrations (`api.Calibration`), as the
    workflow's comparison does: the zero-offsets (sandwich stds, `as_compared`) and the loop
    closure's robot parameters (setup and sensor blocks left out) flagged as drifted, and how many
    of each were compared."""
    entries = [
        comparison.Entry(
            c.campaign.name,
            c.campaign.date,
            c.sensor,
            as_compared(c),
            identity.robot_identity(c.campaign),
            "laser_tracker",
            c.loop.report.parameters,
            c.loop.report.closed,
        )
        for c in (first, second)
    ]
    config = files.read_yaml(REPO / "config.yaml")
    significance = config["comparison"]["significance"]  # as the workflow's
    zero = comparison.drift_between(entries, significance)
    loop = comparison.loop_parameter_drift(entries, significance)
    loop = loop[~loop["block"].isin(comparison.SENSOR_BLOCKS + comparison.CAMPAIGN_BLOCKS)]
    out = {}
    for key, table in (("zero_offsets", zero), ("loop", loop)):
        compared = table[table["status"] == "compared"]
        out[f"{key}_compared"] = len(compared)
        out[f"{key}_flagged"] = compared.loc[compared["flagged"], "parameter"].astype(str).tolist()
        # beyond the threshold, not flagged: a loop that did not close carries what its model lacks
        beyond = (compared["z"].abs() > significance) & ~compared["flagged"].astype(bool)
        out[f"{key}_not_attributed"] = compared.loc[beyond, "parameter"].astype(str).tolist()
    # what the workflow's comparison_prediction says: the change of predicted position at configurations
    # inside both campaigns' measured domains, against the two posteriors' own spread
    predicted = api.compare(first, second, settings=config)["prediction_drift"]
    loop_model = predicted[predicted["model"] == "loop"]
    compared = loop_model[loop_model["draw_pairs"] > 0]  # a null drawn: compared (a turn apart or not)
    out["prediction_compared"] = len(compared)
    out["prediction_turn_apart"] = bool(compared["turn_apart"].any()) if "turn_apart" in compared else False
    out["prediction_flagged"] = bool(compared["flagged"].any())
    # beyond the two posteriors' spread, flagged or not (not: a loop that did not close)
    out["prediction_beyond_null"] = bool(compared["beyond_null"].any()) if "beyond_null" in compared else False
    out["prediction_mean_mm"] = float(compared["aligned_mean_mm"].iloc[0]) if len(compared) else float("nan")
    out["prediction_null_p95_mm"] = (
        float(compared["null_p95_of_aligned_mean_mm"].iloc[0]) if len(compared) else float("nan")
    )
    return out


def added(calibration) -> list[dict]:
    """The loop closure's parameters beyond the zero-offsets and the set-up (display units)."""
    table = calibration.loop.report.parameters
    keep = ~table["block"].isin(("zero_offsets", "registration", "noise"))
    names = ("parameter", "block", "mean_display", "std_display", "prior_std_display", "unit", "status")
    columns = [c for c in names if c in table]
    return table.loc[keep, columns].to_dict("records")


def calibrated(arm: str, truth: str, seed: int, n_random: int, draws: int) -> dict:
    """Every campaign of one group checked (`truth_claims.check`), with the other campaigns'
    validation commands as its elsewhere: {design: (TruthCheck, slices of elsewhere per other, seconds)}."""
    designs = GROUPS[(arm, truth)]
    specs = {d: spec_of(arm, truth, d, seed) for d in designs}
    q = {d: validation_q(s) for d, s in specs.items()}
    out = {}
    for design, spec in specs.items():
        started = time.perf_counter()
        others, parts, start = [d for d in designs if d != design], {}, 0
        for other in others:
            parts[other] = slice(start, start + len(q[other]))
            start += len(q[other])
        checked = check(
            spec, chain_of(spec, REPO), SENSOR, n_random, draws, seed, elsewhere_q=np.vstack([q[o] for o in others])
        )
        out[design] = (checked, parts, time.perf_counter() - started)
        print(f"{arm} {truth} {design} {seed}: {checked.effects} in {out[design][2]:.0f} s", flush=True)
    return out


def group(task: tuple) -> dict:
    """One group of campaigns (arm, truth, seed, n_random, draws): every ordered pair's transfer and
    every pair's drift."""
    arm, truth, seed, n_random, draws = task
    checks = calibrated(arm, truth, seed, n_random, draws)
    cal = {d: c.calibration for d, (c, _, _) in checks.items()}
    sources = {d: models_of(c, c.campaign.name) for d, c in cal.items()}
    targets = {d: target_of(c.campaign, SENSOR, c.laplace.outlier_rows) for d, c in cal.items()}
    designs, pairs, drifts = list(cal), [], []
    for design in designs:
        checked, parts, _ = checks[design]
        there = checked.elsewhere
        for other, part in parts.items():
            row = {"arm": arm, "truth": truth, "seed": seed, "calibrated_on": design, "predicting": other}
            row.update(pair_rms(sources[design]["models"], targets[other]))
            row.update(verdict(row))
            outside = there["error_mm"][part] > there["bound_mm"][part]
            determined = there["determined"][part]
            row["outside_share"] = float(np.mean(outside))
            # where predict states the bound as a measurement (its `determined` column), the 95 % is claimed
            row["determined_share"] = float(np.mean(determined))
            row["outside_determined_share"] = float(np.mean(outside[determined])) if determined.any() else float("nan")
            row["true_loop_rms_mm"] = float(np.sqrt(np.mean(there["error_mm"][part] ** 2)))
            pairs.append(row)
    for i, first in enumerate(designs):
        for second in designs[i + 1 :]:
            changed = GROUPS[(arm, truth)][first].truth != GROUPS[(arm, truth)][second].truth
            drifts.append(
                {"arm": arm, "truth": truth, "seed": seed, "first": first, "second": second, "truth_changed": changed}
                | drift_of(cal[first], cal[second])
            )
    campaigns = [
        {
            "arm": arm,
            "truth": truth,
            "seed": seed,
            "design": d,
            "effects": list(c.effects),
            "added": added(c),
            "noise": (c.loop.report.noise_model or {}).get("chosen"),
            "noise_refused": "refused" in (c.loop.report.noise_model or {}),
            # the zero-offset model's gross errors the loop's final screen took back
            "restored_rows": list((c.loop.report.gross_errors or {}).get("restored", [])),
            "declared_model_error_mm": _in_mm(c.loop.report.declared_model_error("loop")),
            "least_squares_parameters": sources[d]["least_squares_parameters"],
            "check_seconds": checks[d][2],
            "least_squares_seconds": sources[d]["least_squares_seconds"],
        }
        for d, c in cal.items()
    ]
    return {"pairs": pairs, "drifts": drifts, "campaigns": campaigns}


def _in_mm(value: float | None) -> float | None:
    return None if value is None else value * 1e3


def _pair_lines(pairs: list[dict]) -> list[str]:
    lines = [
        "| arm | truth | calibrated on | predicting | seeds | loop-closed RMS (mm) | least squares RMS | loop / LSQ: "
        "median | worst | zero-offset RMS | nominal RMS | outside the bound: mean | max | determined | "
        "outside where determined | targets met |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    keys = list(dict.fromkeys((r["arm"], r["truth"], r["calibrated_on"], r["predicting"]) for r in pairs))
    for arm, truth, source, target in keys:
        part = [
            r
            for r in pairs
            if (r["arm"], r["truth"], r["calibrated_on"], r["predicting"]) == (arm, truth, source, target)
        ]
        ratio = np.array([r["loop_over_baseline"] for r in part])
        outside = np.array([r["outside_share"] for r in part])
        median = {m: np.median([r[f"{m}_rms_mm"] for r in part]) for m in ("loop", "least_squares", "paper", "nominal")}
        met = sum(_met(r) for r in part)
        determined = np.array([r.get("determined_share", np.nan) for r in part])
        claimed = np.array([r.get("outside_determined_share", np.nan) for r in part])
        claimed_text = f"{100 * np.nanmean(claimed):.0f} %" if np.isfinite(claimed).any() else "none determined"
        lines.append(
            f"| {arm} | {truth} | {source} | {target} | {len(part)} | {median['loop']:.4f} | "
            f"{median['least_squares']:.4f} | {np.median(ratio):.2f} | {ratio.max():.2f} | {median['paper']:.4f} | "
            f"{median['nominal']:.4f} | {100 * outside.mean():.0f} % | {100 * outside.max():.0f} % | "
            f"{100 * np.mean(determined):.0f} % | {claimed_text} | "
            f"{met} of {len(part)}{'' if met == len(part) else ' **miss**'} |"
        )
    return lines


def _met(row: dict) -> bool:
    return row["within_baseline"] and row["below_nominal"] and row["not_above_zero_offset"]


def _flagged(part: list[dict], key: str) -> str:
    """Flagged of compared per seed, and the parameters flagged in any."""
    counts = [f"{len(d[f'{key}_flagged'])} of {d[f'{key}_compared']}" for d in part]
    names = sorted({n for d in part for n in d[f"{key}_flagged"]})
    return ", ".join(counts) + (f" ({', '.join(names)})" if names else "")


def _prediction_flagged(part: list[dict]) -> str:
    """Seeds whose loop-closed predictions were flagged of those compared, and each seed's mean change
    beside its null's 95th percentile (mm); '-' for a record made before they were compared."""
    if "prediction_flagged" not in part[0]:
        return "-"
    compared = [d for d in part if d["prediction_compared"]]
    changes = ", ".join(
        f"{d['prediction_mean_mm']:.3f} / {d['prediction_null_p95_mm']:.3f}"
        + (" a turn apart" if d.get("prediction_turn_apart") else "")
        if d["prediction_compared"]
        else "n/c"
        for d in part
    )
    return f"{sum(d['prediction_flagged'] for d in compared)} of {len(compared)} ({changes})"


def _drift_lines(drifts: list[dict]) -> list[str]:
    lines = [
        "| arm | truth | campaigns | truth changed | seeds | zero-offsets flagged | loop parameters flagged | "
        "predicted positions flagged (mean change left after the best rigid motion / its null p95, mm: per seed) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    keys = list(dict.fromkeys((d["arm"], d["truth"], d["first"], d["second"]) for d in drifts))
    for arm, truth, first, second in keys:
        part = [d for d in drifts if (d["arm"], d["truth"], d["first"], d["second"]) == (arm, truth, first, second)]

        lines.append(
            f"| {arm} | {truth} | {first} / {second} | {'yes' if part[0]['truth_changed'] else 'no'} | {len(part)} | "
            f"{_flagged(part, 'zero_offsets')} | {_flagged(part, 'loop')} | {_prediction_flagged(part)} |"
        )
    return lines


def _failure_lines(pairs: list[dict], campaigns: list[dict], shown: int = 3) -> list[str]:
    """Per source campaign (and seed) of a missed transfer: the pairs missed, and the loop's added
    parameters farthest from zero in prior stds (mean +- std, prior std, display units)."""
    missed = [r for r in pairs if not _met(r)]
    if not missed:
        return []
    lines = [
        "Where a target was missed, the source's added parameters farthest from zero in prior stds:",
        "",
        "| arm | truth | calibrated on | seed | missed on (loop / LSQ; loop, zero-offset RMS mm) | largest added "
        "parameters: mean +- std (prior std) |",
        "|---|---|---|---|---|---|",
    ]
    keys = list(dict.fromkeys((r["arm"], r["truth"], r["calibrated_on"], r["seed"]) for r in missed))
    for arm, truth, design, seed in keys:
        rows = [
            r for r in missed if (r["arm"], r["truth"], r["calibrated_on"], r["seed"]) == (arm, truth, design, seed)
        ]
        source = next(
            c for c in campaigns if (c["arm"], c["truth"], c["design"], c["seed"]) == (arm, truth, design, seed)
        )
        ranked = sorted(
            (p for p in source["added"] if np.isfinite(p.get("prior_std_display", np.nan))),
            key=lambda p: -abs(p["mean_display"]) / p["prior_std_display"],
        )[:shown]
        where = "; ".join(
            f"{r['predicting']} ({r['loop_over_baseline']:.2f}; {r['loop_rms_mm']:.3f}, {r['paper_rms_mm']:.3f})"
            for r in rows
        )
        largest = "; ".join(
            f"{p['parameter']} {p['mean_display']:.3g} +- {p['std_display']:.2g} ({p['prior_std_display']:.3g} {p['unit']})"
            for p in ranked
        )
        lines.append(f"| {arm} | {truth} | {design} | {seed} | {where} | {largest or 'none added'} |")
    return lines


def _verdict(record: dict) -> str:
    """The targets' pass or fail over every transfer and campaign pair of the record."""
    pairs, drifts = record["pairs"], record["drifts"]
    effects = {(c["arm"], c["truth"], c["design"], c["seed"]): c["effects"] for c in record["campaigns"]}
    met = sum(_met(r) for r in pairs)
    ratio = sum(r["within_baseline"] for r in pairs)
    nominal = sum(r["below_nominal"] for r in pairs)
    farther = [r for r in pairs if not r["not_above_zero_offset"]]
    told = [r for r in farther if not r.get("not_significantly_above_zero_offset", False)]
    # the loop added nothing: the zero-offset model's form, its estimate the loop's refit
    same_form = sum(not effects[(r["arm"], r["truth"], r["calibrated_on"], r["seed"])] for r in farther)
    restored = {
        (c["arm"], c["truth"], c["design"], c["seed"]): bool(c.get("restored_rows")) for c in record["campaigns"]
    }
    other_rows = sum(
        restored.get((r["arm"], r["truth"], r["calibrated_on"], r["seed"]), False)
        and not effects[(r["arm"], r["truth"], r["calibrated_on"], r["seed"])]
        for r in farther
    )
    rows_known = "restored_rows" in record["campaigns"][0] if record["campaigns"] else False
    worst = max((r["loop_rms_mm"] / r["paper_rms_mm"] for r in farther), default=1.0)
    unchanged = [d for d in drifts if not d["truth_changed"]]
    false_drift = [d for d in unchanged if d["zero_offsets_flagged"] or d["loop_flagged"]]
    remounted = sum("marker remounted" in (d["first"], d["second"]) for d in false_drift)
    changed = [d for d in drifts if d["truth_changed"]]
    seen = sum(bool(d["zero_offsets_flagged"] or d["loop_flagged"]) for d in changed)
    unattributed = [
        sum(bool(d.get("zero_offsets_not_attributed") or d.get("loop_not_attributed")) for d in part)
        for part in (unchanged, changed)
    ]
    outside = sum(r["outside_share"] > MAX_OUTSIDE for r in pairs)
    claimed = [r for r in pairs if np.isfinite(r.get("outside_determined_share", np.nan))]
    claimed_outside = sum(r["outside_determined_share"] > MAX_OUTSIDE for r in claimed)
    n = len(pairs)
    by_prediction = ""
    if drifts and "prediction_flagged" in drifts[0]:
        false_predicted = sum(d["prediction_flagged"] for d in unchanged)
        seen_predicted = sum(d["prediction_flagged"] for d in changed)
        beyond = [sum(d.get("prediction_beyond_null", False) for d in part) for part in (unchanged, changed)]
        apart = [
            sum(d.get("prediction_beyond_null", False) and d.get("prediction_turn_apart", False) for d in part)
            for part in (unchanged, changed)
        ]
        by_prediction = (
            f" By predicted positions inside both campaigns' domains (the workflow's prediction drift, loop-closed "
            f"model): flagged where the truth did not change on {false_predicted} of {len(unchanged)} pairs, "
            f"where it changed on {seen_predicted} of {len(changed)} (beyond the posteriors' spread, flagged or not: "
            f"{beyond[0]} and {beyond[1]}; of them compared a turn apart, shown and not flagged: {apart[0]} and "
            f"{apart[1]})."
        )
    return (
        f"Targets: loop-closed within {WITHIN}x least squares on {ratio} of {n} transfers "
        f"({'pass' if ratio == n else 'FAIL'}); below the nominal model on {nominal} of {n} "
        f"({'pass' if nominal == n else 'FAIL'}); no farther than the zero-offset model on {n - len(farther)} of {n} "
        f"({'pass' if not farther else 'FAIL'}: {same_form} of the {len(farther)} misses from a loop that added "
        f"nothing, the zero-offset model's form refitted"
        + (
            f" ({other_rows} of them on other rows: the loop's screen took back rows the zero-offset model's "
            f"screen left out, in {sum(restored.values())} of the {len(restored)} campaigns)"
            if rows_known
            else ""
        )
        + f"; {len(told)} of them farther by more than "
        f"{SIGNIFICANT:.0f} standard errors of the rows' paired difference; worst loop / zero-offset {worst:.2f}); "
        f"all three on {met}. "
        f"Drift flagged where the truth did not change: {len(false_drift)} of {len(unchanged)} campaign pairs "
        f"({'pass' if not false_drift else 'FAIL'}; {remounted} of them with the marker remounted, a set-up change); "
        f"where it changed: {seen} of {len(changed)}; beyond the stds but not attributed to the robot (a loop that "
        f"did not close): {unattributed[0]} and {unattributed[1]}.{by_prediction} Transfers with more than {100 * MAX_OUTSIDE:.0f} % of the "
        f"commands outside their bound: {outside} of {n}; of the commands whose bound predict states as determined "
        f"(near the data): {claimed_outside} of the {len(claimed)} transfers with any. Wall time {record['seconds']:.0f} s."
    )


def markdown(record: dict) -> str:
    pairs, drifts, campaigns = record["pairs"], record["drifts"], record["campaigns"]
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_transfer.py`: {record['seeds']} seeds per group "
        f"(seeds {record['first']}-{record['first'] + record['seeds'] - 1}), {record['n_random']} random "
        f"configurations and {record['draws']} draws per check; RMS over the target's validation rows after its "
        "registration is refitted (mm, medians over the seeds); loop / LSQ: the loop-closed model's RMS over "
        "complete-model least squares' on the same pair; outside the bound: the target's validation commands "
        "where the true error of the source's `remaster predict` exceeds its 95 % bound; targets met: loop / LSQ "
        f"<= {WITHIN}, loop no farther than the zero-offset and the nominal model.",
        "",
        *_pair_lines(pairs),
        "",
        "Drift between the campaigns of a group (`comparing.comparison`: |z| > 3, flagged of compared per seed):",
        "",
        *_drift_lines(drifts),
        "",
        "| arm | truth | campaign | effects the loop added (per seed) | check (s) |",
        "|---|---|---|---|---|",
    ]
    keys = list(dict.fromkeys((c["arm"], c["truth"], c["design"]) for c in campaigns))
    for arm, truth, design in keys:
        part = [c for c in campaigns if (c["arm"], c["truth"], c["design"]) == (arm, truth, design)]
        effects = "; ".join(", ".join(c["effects"]) or "none" for c in part)
        lines.append(
            f"| {arm} | {truth} | {design} | {effects} | {np.median([c['check_seconds'] for c in part]):.0f} |"
        )
    lines += ["", *_failure_lines(pairs, campaigns)]
    lines += ["", _verdict(record)]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--first", type=int, default=101)
    parser.add_argument("--n-random", type=int, default=50, help="random configurations per check")
    parser.add_argument("--draws", type=int, default=400, help="posterior draws per bound")
    parser.add_argument("--groups", default="", help="arm:truth,... (default: every group)")
    parser.add_argument("--rewrite", action="store_true", help="the tables again from results/transfer.json")
    args = parser.parse_args()
    if args.rewrite:
        record = json.loads((RESULTS / "transfer.json").read_text(encoding="utf-8"))
        publish(RESULTS, "transfer", record, markdown(record), REPO / "docs" / "validation.md")
        return
    started = time.perf_counter()
    chosen = [tuple(g.split(":")) for g in args.groups.split(",") if g] or list(GROUPS)
    tasks = [
        (a, t, s, args.n_random, args.draws) for s in range(args.first, args.first + args.seeds) for a, t in chosen
    ]
    results = []
    for i, task in enumerate(tasks):
        results.append(group(task))
        if (i + 1) % len(chosen) == 0:  # every seed done: published, so that a stopped run keeps its seeds
            record = {
                "date": date.today().isoformat(),
                "seeds": (i + 1) // len(chosen),
                "first": args.first,
                "n_random": args.n_random,
                "draws": args.draws,
                **{key: [row for r in results for row in r[key]] for key in ("pairs", "drifts", "campaigns")},
                "seconds": time.perf_counter() - started,
            }
            publish(RESULTS, "transfer", record, markdown(record), REPO / "docs" / "validation.md")


if __name__ == "__main__":
    main()
