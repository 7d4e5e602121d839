"""The cyclic-error scenario at its full size and the data density the joint-space residual model needs.

The truth (`arm_kinds.cyclic_truth`): a simulated iiwa with zero-offsets and the
cyclic transmission errors J2 0.025 deg sin(q2 + 0.3) + 0.012 deg sin(2 q2 + 1.1), J4 0.03 deg
sin(q4 - 0.7), nothing else; joint 3 held at 0 by the planner (the paper's). Two sensors measure the
same campaign as in the twin (data/simulation/kuka-twin.yaml, without its marker errors): a laser
tracker (10 um, its range/transverse noise offered) and a motion capture (30 um, kind
`motion_capture`), each calibrated alone by the pipeline's stages (`truth_claims.check`:
registration, Laplace fit, loop closure with config.yaml's settings, `remaster predict`); the
scenario is `remaster.campaigns.arm_kinds.cyclic_case`.

The sweep: optimization sets of 20, 30, 40, 80 and 152 configurations over 5, 6, 8, 17 and 32 poses (the
paper's ~4.75 configurations per pose, 5 poses at least for the 5 folds; 152 / 32 is the scenario's full size), a validation set like the
twin's (32 poses, 156 configurations) for all, several seeds each. Per run: the effects added and
their side, the joints and orders `joint_harmonics` names, validation RMS per axis / noise, and the
share of configurations whose true error is within `remaster predict`'s per-command 95 % bound:
- across the limits (uniform in the joint limits: joint 3, never measured, rests on its priors),
- inside the measured ranges (uniform in each joint's measured interval, `domain.MeasuredDomain`),
  split into those within GAP_DEG of a measured angle on every joint and those in a gap of the
  measured angles (the interval is not the data: the planner's poses leave holes in it),
- at the validation set's commands (the planner's own configurations).
Also the sensor-side candidates' scores in the last round they were offered (evidence gain, nats;
cross-validated fall, standard errors), to show why they were or were not added.

Run from the repository root: nice python benchmarks/bench_cyclic_case.py [seed ...] (default 3 4 5 6).
Writes benchmarks/results/cyclic_case.json and cyclic_case.md.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.truth_claims import check  # noqa: E402
from remaster.campaigns.arm_kinds import CYCLIC_SETS, chain_of, cyclic_case, true_f  # noqa: E402

SENSORS = ("laser_tracker", "motion_capture")
# optimization set (configurations, poses): ~4.75 configurations per pose, 152 / 32 the scenario's full size;
# 20 over 5, not 4: the loop closure's cross-validation needs as many poses as folds (cv_folds: 5)
SIZES = ((20, 5), (30, 6), (40, 8), (80, 17), (152, 32))
VALIDATION = CYCLIC_SETS["validation"]  # the twin's: 32 poses, 156 configurations
TRUTH_NAMED = {"q2": [1, 2], "q4": [1]}
SENSOR_SIDE = ("sensor_scale", "sensor_distortion")
# a configuration inside the ranges is "near the data" when every joint is this close to a measured angle
GAP_DEG = 10.0
N_RANDOM, DRAWS = 300, 500
OUT = REPO / "benchmarks" / "results"


def scenario(seed: int, configurations: int, poses: int) -> dict:
    return cyclic_case(
        seed, {"optimization": {"poses": poses, "configurations": configurations}, "validation": VALIDATION}
    )


def last_scores(report, candidate: str) -> dict | None:
    """The candidate's scores in the last round it was offered (evidence gain, CV fall in SE, passed)."""
    rows = report.candidates.get(candidate) or []
    if not rows:
        return None
    row = rows[-1]
    return {
        "round": row.get("round"),
        "log_evidence_gain": row.get("log_evidence_gain"),
        "cv_mse_fall_in_se": row.get("cv_mse_fall_in_se"),
        "passed": row.get("passed"),
        "first_round_log_evidence_gain": rows[0].get("log_evidence_gain"),
        "first_round_cv_mse_fall_in_se": rows[0].get("cv_mse_fall_in_se"),
        "first_round_passed": rows[0].get("passed"),
    }


def gaps_deg(q: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """(n, N) deg: each configuration's distance, per joint, to the nearest measured angle of that joint."""
    return np.degrees(np.abs(q[:, None, :] - measured[None, :, :]).min(axis=1))


def joint_error_z(result, spec: dict, joint: int, grid: int = 61) -> dict | None:
    """How far the posterior of joint `joint`'s whole angle error, zero-offset + f_j(q), lies from the
    truth's across the joint's measured interval, in posterior standard deviations (MCMC samples):
    the largest |z| at angles within GAP_DEG of a measured angle and in the gaps between them, and
    the share of the interval in gaps. None without samples or when the block was not added."""
    samples, orders = result.samples, result.report.harmonic_orders
    columns = [f"joint_harmonics.q{joint}.{f}{k}" for k in range(1, orders + 1) for f in ("cos", "sin")]
    if samples is None or not len(samples) or any(c not in samples for c in columns):
        return None
    measured = result.measured_q[:, joint - 1]
    q = np.linspace(measured.min(), measured.max(), grid)
    offset = samples[f"zero_offsets.q{joint}"].to_numpy(float)[:, None]
    draws = offset + sum(
        samples[f"joint_harmonics.q{joint}.cos{k}"].to_numpy(float)[:, None] * np.cos(k * q)
        + samples[f"joint_harmonics.q{joint}.sin{k}"].to_numpy(float)[:, None] * np.sin(k * q)
        for k in range(1, orders + 1)
    )
    truth = np.radians(spec["truth"]["zero_offsets_deg"][joint - 1]) + true_f(joint, q)
    z = (draws.mean(axis=0) - truth) / draws.std(axis=0)
    near = np.degrees(np.abs(q[:, None] - measured[None, :]).min(axis=1)) <= GAP_DEG
    return {
        "max_abs_z_near_data": float(np.abs(z[near]).max()) if near.any() else None,
        "max_abs_z_in_gaps": float(np.abs(z[~near]).max()) if (~near).any() else None,
        "gap_share_of_interval": float(np.mean(~near)),
    }


def run(sensor: str, seed: int, configurations: int, poses: int) -> dict:
    spec = scenario(seed, configurations, poses)
    started = time.perf_counter()
    result = check(spec, chain_of(spec, REPO), sensor, n_random=N_RANDOM, draws=DRAWS, seed=seed)
    report = result.report
    sides = dict(report.effects_sides)
    harmonics = report.harmonics
    named = dict(harmonics["named"]) if harmonics else {}
    terms = {
        f"{row['joint']}.{row['order']}": {
            "amplitude_deg": row["amplitude_deg"],
            "amplitude_std_deg": row["amplitude_std_deg"],
            "p_value": row["p_value"],
            "named": row["named"],
        }
        for row in (harmonics["terms"] if harmonics else [])
        if row["seen_by_data"]
    }
    # inside the measured ranges: near the measured angles on every joint, or in a gap of them
    gap = gaps_deg(result.domain_q, result.measured_q)
    near = gap.max(axis=1) <= GAP_DEG
    held = result.domain_error_mm <= result.domain_bound_mm
    widest = np.argmax(gap, axis=1)  # the joint farthest from its measured angles
    missed = ~held
    miss_joints = {f"q{j + 1}": int(np.sum(missed & ~near & (widest == j))) for j in range(gap.shape[1])}
    closure = report.closure
    return {
        "sensor": sensor,
        "seed": seed,
        "configurations": configurations,
        "poses": poses,
        "effects": list(result.effects),
        "sides": sides,
        "sensor_side_added": [e for e in result.effects if e in SENSOR_SIDE],
        "named": named,
        "named_as_truth": named == TRUTH_NAMED,
        "terms": terms,
        "residual_gp_added": bool(report.residual_gp and report.residual_gp.get("added")),
        "noise_model": report.noise_model.get("chosen"),
        "closed": bool(closure.get("closed")),
        "validation_over_noise": result.validation_rms_per_axis_mm / result.noise_mm,
        "held_across_limits": result.held_fraction,
        "held_inside_ranges": result.domain_held_fraction,
        "inside_near_data_share": float(np.mean(near)),
        "held_inside_near_data": float(np.mean(held[near])) if near.any() else None,
        "held_inside_in_gaps": float(np.mean(held[~near])) if (~near).any() else None,
        "misses_in_gaps_by_widest_joint": miss_joints,
        "held_at_validation_commands": result.planned_held_fraction,
        "true_error_p95_mm": {
            "across_limits": float(np.quantile(result.error_mm, 0.95)),
            "inside_ranges": float(np.quantile(result.domain_error_mm, 0.95)),
            "validation_commands": float(np.quantile(result.planned_error_mm, 0.95)),
        },
        "bound_median_mm": {
            "across_limits": float(np.median(result.bound_mm)),
            "inside_ranges": float(np.median(result.domain_bound_mm)),
            "validation_commands": float(np.median(result.planned_bound_mm)),
        },
        "measured_q4_min_abs_deg": float(np.degrees(np.abs(result.measured_q[:, 3]).min())),
        "joint_error_z": {f"q{j}": joint_error_z(result, spec, j) for j in (2, 4)},
        "sensor_side_scores": {c: last_scores(report, c) for c in SENSOR_SIDE},
        "joint_harmonics_scores": last_scores(report, "joint_harmonics"),
        "seconds": time.perf_counter() - started,
    }


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def cells(rows: list[dict]) -> list[dict]:
    """One row per sensor and size over the seeds."""
    out = []
    for sensor in SENSORS:
        for configurations, poses in SIZES:
            runs = [r for r in rows if r["sensor"] == sensor and r["configurations"] == configurations]
            if not runs:
                continue
            n = len(runs)
            out.append(
                {
                    "sensor": sensor,
                    "configurations": configurations,
                    "poses": poses,
                    "seeds": n,
                    "joint_harmonics_added": sum("joint_harmonics" in r["effects"] for r in runs),
                    "only_joint_harmonics": sum(r["effects"] == ["joint_harmonics"] for r in runs),
                    "sensor_side_added": sum(bool(r["sensor_side_added"]) for r in runs),
                    "named_as_truth": sum(r["named_as_truth"] for r in runs),
                    "q2_order2_named": sum(2 in r["named"].get("q2", []) for r in runs),
                    "effects_seen": sorted({"+".join(r["effects"]) or "none" for r in runs}),
                    "named_seen": sorted({json.dumps(r["named"], sort_keys=True) for r in runs}),
                    "validation_over_noise_mean": _mean(r["validation_over_noise"] for r in runs),
                    "validation_over_noise_max": max(r["validation_over_noise"] for r in runs),
                    "held_across_limits_mean": _mean(r["held_across_limits"] for r in runs),
                    "held_across_limits_min": min(r["held_across_limits"] for r in runs),
                    "held_inside_ranges_mean": _mean(r["held_inside_ranges"] for r in runs),
                    "held_inside_ranges_min": min(r["held_inside_ranges"] for r in runs),
                    "held_inside_near_data_mean": _mean(r["held_inside_near_data"] for r in runs),
                    "held_inside_in_gaps_mean": _mean(r["held_inside_in_gaps"] for r in runs),
                    "inside_near_data_share_mean": _mean(r["inside_near_data_share"] for r in runs),
                    "held_at_validation_commands_mean": _mean(r["held_at_validation_commands"] for r in runs),
                    "bound_median_across_limits_mm": _median(r["bound_median_mm"]["across_limits"] for r in runs),
                    "bound_median_inside_ranges_mm": _median(r["bound_median_mm"]["inside_ranges"] for r in runs),
                    "true_error_p95_inside_ranges_mm": _median(r["true_error_p95_mm"]["inside_ranges"] for r in runs),
                    "joint_harmonics_first_offered": _scores(runs, "joint_harmonics"),
                    "joint_error_max_abs_z": {
                        f"q{j}": {
                            where: _largest((r["joint_error_z"][f"q{j}"] or {}).get(f"max_abs_z_{where}") for r in runs)
                            for where in ("near_data", "in_gaps")
                        }
                        for j in (2, 4)
                    },
                    **{f"{c}_first_offered": _scores(runs, c) for c in SENSOR_SIDE},
                }
            )
    return out


def _largest(values) -> float | None:
    values = [v for v in values if v is not None]
    return max(values) if values else None


def _z(value) -> str:
    return "-" if value is None else f"{value:.1f}"


def _median(values) -> float:
    return float(np.median(list(values)))


def _scores(runs: list[dict], candidate: str) -> dict:
    """A candidate's scores when first offered, over the seeds: median and largest evidence gain
    (nats) and cross-validated fall (standard errors)."""
    found = [
        r["joint_harmonics_scores"] if candidate == "joint_harmonics" else r["sensor_side_scores"][candidate]
        for r in runs
    ]
    gains = [f["first_round_log_evidence_gain"] for f in found if f]
    falls = [f["first_round_cv_mse_fall_in_se"] for f in found if f]
    return {
        "log_evidence_gain_median": _median(gains),
        "log_evidence_gain_max": max(gains),
        "cv_fall_in_se_median": _median(falls),
        "cv_fall_in_se_max": max(falls),
        "passed_when_first_offered": sum(bool(f and f["first_round_passed"]) for f in found),
    }


def _pct(value) -> str:
    return "-" if value is None else f"{100 * value:.0f} %"


def markdown(summary: list[dict], seeds: list[int]) -> str:
    lines = [
        "# The cyclic-error scenario: what the joint-space residual model needs",
        "",
        "Written by benchmarks/bench_cyclic_case.py (its docstring says what is simulated and measured); "
        f"seeds {', '.join(map(str, seeds))}; counts are over the seeds. Bound coverage: the share of "
        "configurations whose true error is within `remaster predict`'s per-command 95 % bound, mean over the "
        f"seeds (min in brackets). 'Near data': inside the measured ranges and within {GAP_DEG:.0f} deg of a "
        "measured angle on every joint; 'gaps': inside the ranges, farther than that on some joint.",
        "",
        "| Sensor | Configurations / poses | joint_harmonics added | only it | sensor-side added "
        "| q2 (1, 2), q4 (1) named | q2 order 2 named | val RMS / noise mean (max) | across limits "
        "| inside ranges | near data (share) | in gaps | validation commands |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in summary:
        n = c["seeds"]
        lines.append(
            f"| {c['sensor']} | {c['configurations']} / {c['poses']} | {c['joint_harmonics_added']}/{n} "
            f"| {c['only_joint_harmonics']}/{n} | {c['sensor_side_added']}/{n} | {c['named_as_truth']}/{n} "
            f"| {c['q2_order2_named']}/{n} "
            f"| {c['validation_over_noise_mean']:.2f} ({c['validation_over_noise_max']:.2f}) "
            f"| {_pct(c['held_across_limits_mean'])} ({_pct(c['held_across_limits_min'])}) "
            f"| {_pct(c['held_inside_ranges_mean'])} ({_pct(c['held_inside_ranges_min'])}) "
            f"| {_pct(c['held_inside_near_data_mean'])} ({_pct(c['inside_near_data_share_mean'])}) "
            f"| {_pct(c['held_inside_in_gaps_mean'])} "
            f"| {_pct(c['held_at_validation_commands_mean'])} |"
        )
    lines += [
        "",
        "Scores when first offered (forward round 1, the zero-offset model), median over the seeds "
        "(largest in brackets): evidence gain in nats (threshold 5), cross-validated fall in standard "
        "errors (threshold t(K-1)); the bound's median (mm) across the limits and inside the measured "
        "ranges against the true error's 95th percentile inside the ranges (median over the seeds).",
        "",
        "| Sensor | Configurations | joint_harmonics gain | its CV fall | sensor_scale gain | its CV fall "
        "| sensor_distortion gain | its CV fall | passed both (of the seeds): joint_harmonics, sensor_scale, "
        "sensor_distortion | bound across limits | bound inside ranges | true error p95 inside |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in summary:
        row = [c["sensor"], str(c["configurations"])]
        for candidate in ("joint_harmonics", *SENSOR_SIDE):
            f = c[f"{candidate}_first_offered"]
            row.append(f"{f['log_evidence_gain_median']:.1f} ({f['log_evidence_gain_max']:.1f})")
            row.append(f"{f['cv_fall_in_se_median']:.1f} ({f['cv_fall_in_se_max']:.1f})")
        row.append(
            ", ".join(
                str(c[f"{k}_first_offered"]["passed_when_first_offered"]) for k in ("joint_harmonics", *SENSOR_SIDE)
            )
        )
        row += [
            f"{c['bound_median_across_limits_mm']:.3f}",
            f"{c['bound_median_inside_ranges_mm']:.3f}",
            f"{c['true_error_p95_inside_ranges_mm']:.3f}",
        ]
        lines.append("| " + " | ".join(row) + " |")
    lines += [
        "",
        "Joints 2 and 4's whole angle error (zero-offset + f_j) against the truth's across each joint's "
        f"measured interval, in posterior standard deviations (MCMC samples): the largest |z| over the seeds "
        f"at angles within {GAP_DEG:.0f} deg of a measured angle and in the gaps between them.",
        "",
        "| Sensor | Configurations | q2 near data | q2 in gaps | q4 near data | q4 in gaps |",
        "|---|---|---|---|---|---|",
    ]
    for c in summary:
        z = c["joint_error_max_abs_z"]
        lines.append(
            f"| {c['sensor']} | {c['configurations']} | {_z(z['q2']['near_data'])} | {_z(z['q2']['in_gaps'])} "
            f"| {_z(z['q4']['near_data'])} | {_z(z['q4']['in_gaps'])} |"
        )
    lines += ["", "Effects added and joints named, per cell:", ""]
    for c in summary:
        lines.append(
            f"- {c['sensor']}, {c['configurations']}: effects {'; '.join(c['effects_seen'])}; named "
            f"{'; '.join(c['named_seen'])}"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    seeds = [int(s) for s in sys.argv[1:]] or [3, 4, 5, 6]
    rows = []
    for configurations, poses in SIZES:
        for seed in seeds:
            for sensor in SENSORS:
                rows.append(run(sensor, seed, configurations, poses))
                r = rows[-1]
                print(
                    f"{sensor} {configurations}/{poses} seed {seed}: {r['effects']} named {r['named']} "
                    f"val/noise {r['validation_over_noise']:.2f} held across {r['held_across_limits']:.2f} "
                    f"inside {r['held_inside_ranges']:.2f} (near {r['held_inside_near_data']}, gaps "
                    f"{r['held_inside_in_gaps']}) validation cmds {r['held_at_validation_commands']:.2f} "
                    f"({r['seconds']:.0f} s)",
                    flush=True,
                )
    summary = cells(rows)
    OUT.mkdir(parents=True, exist_ok=True)
    content = {
        "what": "the cyclic-error scenario: benchmarks/bench_cyclic_case.py",
        "seeds": seeds,
        "sizes": [{"configurations": c, "poses": p} for c, p in SIZES],
        "validation": VALIDATION,
        "gap_deg": GAP_DEG,
        "summary": summary,
        "runs": rows,
    }
    (OUT / "cyclic_case.json").write_text(json.dumps(content, indent=1, sort_keys=True) + "\n")
    (OUT / "cyclic_case.md").write_text(markdown(summary, seeds))


if __name__ == "__main__":
    main()
