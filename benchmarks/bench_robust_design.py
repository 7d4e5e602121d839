"""Does a design that allows for what the model lacks (`remaster plan --criterion robust`) calibrate
better where the model is wrong? Judged first on the simulator with a discrepancy the error model
cannot take, then (once, with the prior fixed before) on the real UR5 grid's validation rows.

Run from the repository root: python benchmarks/bench_robust_design.py [--quick]
Writes benchmarks/results/robust_planner.json and robust_planner.md (docs/planning.md quotes them).

Simulator: the iiwa of bench_planner (`iiwa_rigid_link_errors`: rigid errors in every fixed
transform, tracker 10 um), plus a cyclic error of the joint angles (the cyclic-error scenario,
`arm_kinds.CYCLIC_TERMS`: orders 1 and 2 on joint 2, order 1 on joint 4, amplitudes
scaled by CYCLIC_SCALE) that the complete error model does not have, so its calibration is
biased wherever it is measured. Designs among the same generated candidates: workspace (the p95
criterion), robust (this criterion, its DEFAULT prior: the sensor's noise as signal, each joint's
range over the workspace as lengthscale: not the truth's harmonics, which it cannot express),
D-optimal, random, paper. Score: the true error across the workspace (EVALUATION random
configurations): RMS per axis, mean and p95 of the distance.

UR5 (data/raw/jacobi-ur5-gts3800): as bench_planner: N of the 1,000 optimization rows chosen as
candidates (the workspace the candidates' joint box), against N and 3N random rows, scored by the
validation RMS per axis on its 20 validation rows. Robust with the default prior (signal = the stated
noise; the verdict's design, fixed before this run), and with the discrepancy the campaign itself
shows: the residual GP's hyperparameters fitted (`gp.residual.fit_hyperparameters`) to the
residuals of the complete error model calibrated on all 1,000 optimization rows (never the
validation rows): what a previous campaign of the same arm would give.

UR5 oracle (`ur5_oracle`): how far any choice of rows can go, without the validation rows: the
optimization rows split into candidates and a held-out proxy, and rows chosen by an oracle that sees
the proxy's errors, against N and 3N random candidates.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from bench_planner import (  # noqa: E402
    SENSOR,
    UR5,
    calibrate,
    config_priors,
    paper_design,
    sensor_of,
    simulated,
    subset_sensor,
    validation_rms,
    with_block,
)

from remaster.campaigns import folders  # noqa: E402
from remaster.campaigns.arm_kinds import cyclic_truth, iiwa_rigid_link_errors  # noqa: E402
from remaster.campaigns.simulation import measure, true_sensor_positions  # noqa: E402
from remaster.inference import fit  # noqa: E402
from remaster.inference.gp import residual  # noqa: E402
from remaster.inference.readings import readings  # noqa: E402
from remaster.planning import design, plan_inputs  # noqa: E402
from remaster.planning import design_posterior as dp  # noqa: E402
from remaster.planning import robust_design as dd  # noqa: E402
from remaster.robot import planning  # noqa: E402

SIM_N = (10, 20, 40, 80, 120)
UR5_N = (10, 20, 40, 60, 100)
REPEATS = 3
DRAWS = 5
EVALUATION = 1000
CANDIDATE_POSES = 300
# of the cyclic-error scenario's amplitudes (0.025 / 0.012 / 0.030 deg): a discrepancy of a few x the noise
CYCLIC_SCALE = 0.25
OUT = REPO / "benchmarks" / "results"
# the blocks of docs/planning.md (robust_planner.md whole) and README.md (its verdicts) that show the
# results (tests/planning/test_robust_design.py checks them)
DOCUMENTS = (REPO / "docs" / "planning.md", REPO / "README.md")
BEGIN, END = "<!-- bench_robust_design:begin -->", "<!-- bench_robust_design:end -->"


def discrepancy_spec() -> dict:
    spec = iiwa_rigid_link_errors()
    terms = cyclic_truth()
    for term in terms:
        term["amplitude_deg"] = [CYCLIC_SCALE * a for a in term["amplitude_deg"]]
    spec["truth"]["cyclic_error"] = terms
    spec["name"] = "rigid-link-errors-and-cyclic-error"
    return spec


def simulator(repeats: int, grid) -> dict:
    setting = simulated(discrepancy_spec())
    chain, marker, robot, device = setting.chain, setting.marker, setting.robot, setting.device
    origin, sight, priors, model = setting.origin, setting.sight, setting.priors, setting.model
    q_eval = design.evaluation_configurations(chain, EVALUATION, np.random.default_rng(2035))
    true_eval = true_sensor_positions(chain, robot, device, q_eval)
    largest = max(grid)
    rows, seconds = [], []
    for repeat in range(repeats):
        rng = np.random.default_rng(100 + repeat)
        candidates = plan_inputs.generated_candidates(chain, origin, marker, rng, poses=CANDIDATE_POSES)
        q_c = plan_inputs.configurations(candidates, chain.n_joints)
        plan_eval = design.evaluation_configurations(chain, design.EVALUATION_CONFIGURATIONS, rng)
        jc, je, prior = model.whitened_jacobian(q_c), model.jacobian(plan_eval), model.prior_information()
        started = time.time()
        robust = dd.robust_design(
            jc,
            q_c,
            je,
            plan_eval,
            prior,
            dd.workspace_discrepancy(plan_eval, device.noise),
            device.noise,
            budget=largest,
        )
        seconds.append(time.time() - started)
        workspace = design.greedy_design(jc, je, prior, budget=largest)
        d_optimal = design.greedy_design(jc, je, prior, budget=largest, criterion="d-optimal")
        for n in grid:
            designs = {
                "robust": q_c[robust.chosen[:n]],
                "workspace": q_c[workspace.chosen[:n]],
                "d_optimal": q_c[d_optimal.chosen[:n]],
                "random": plan_inputs.configurations(
                    planning.plan_random(chain, "optimization", [sight], rng, n_configurations=n).table, chain.n_joints
                ),
                "paper": paper_design(chain, origin, sight, n, rng),
            }
            for kind, q in designs.items():
                xyz = measure(chain, robot, device, q, rng)
                fitted, theta = calibrate(chain, sensor_of(chain, q, xyz, marker, device.noise), priors)
                error = fitted.on(dp.probe_readings(q_eval)).predict(theta) - true_eval
                distance = np.linalg.norm(error, axis=1) / 1e-3
                rows.append(
                    {
                        "repeat": repeat,
                        "design": kind,
                        "n": n,
                        "true_rms_mm": float(np.sqrt(np.mean(error**2)) / 1e-3),
                        "true_mean_mm": float(np.mean(distance)),
                        "true_p95_mm": float(np.quantile(distance, 0.95)),
                        "robust_expected_rms_mm": float(robust.bounds["expected_rms_mm"].iloc[n])
                        if kind == "robust"
                        else None,
                    }
                )
                print(f"sim {repeat} {kind:9s} n={n:4d}: rms {rows[-1]['true_rms_mm']:.4f} mm", flush=True)
    # every candidate of the last repeat measured once (with noise) and fitted: not a floor (the
    # candidates are not distributed as the workspace, and designs of 40 or more do better)
    xyz = measure(chain, robot, device, q_c, np.random.default_rng(0))
    fitted, theta = calibrate(chain, sensor_of(chain, q_c, xyz, marker, device.noise), priors)
    floor = fitted.on(dp.probe_readings(q_eval)).predict(theta) - true_eval
    table = pd.DataFrame(rows)
    median = table.groupby(["design", "n"])[["true_rms_mm", "true_mean_mm", "true_p95_mm"]].median()
    return {
        "scenario": f"iiwa_rigid_link_errors + cyclic joint error (the cyclic-error scenario's terms x {CYCLIC_SCALE}), "
        "tracker 10 um",
        "evaluation_configurations": EVALUATION,
        "candidates_per_repeat": int(len(q_c)),
        "repeats": repeats,
        "robust_planner_seconds": seconds,
        "all_candidates_true_rms_mm": float(np.sqrt(np.mean(floor**2)) / 1e-3),
        "noise_mm": float(device.noise) / 1e-3,
        "rows": table.to_dict(orient="records"),
        "median": median.reset_index().to_dict(orient="records"),
    }


def expected_rms(jw, q, prior, je, q_eval, discrepancy, sigma) -> float:
    """The robust criterion's expected RMS per axis (mm) of the calibration from rows jw (n, 3, P) at q."""
    return float(np.sqrt(np.mean(dd.expected_squared_errors(jw, q, prior, je, q_eval, discrepancy, sigma)) / 3) / 1e-3)


def campaign_discrepancy(chain, sensor, priors) -> dd.Discrepancy:
    """The residual GP of the complete error model calibrated on all optimization rows (robot frame
    residuals; the kernel is the same on the three axes, so the frame does not matter)."""
    model, theta = calibrate(chain, sensor, priors)
    q = readings(chain, sensor, "optimization").q
    hyper = residual.fit_hyperparameters(q, model.residuals(theta).reshape(-1, 3))
    return dd.Discrepancy(hyper.lengthscales, hyper.signal_std)


def ur5(draws: int, grid) -> dict:
    campaign = folders.read_campaign(UR5, repo_root=REPO)
    chain, sensor = campaign.chain, campaign.sensors[SENSOR]
    priors = config_priors(campaign.robot)
    rows_opt = sensor.measured_rows("optimization")
    t_nr = fit.register(chain, sensor).t_nr
    model = dp.complete_error_model(chain, sensor.marker, t_nr, priors, sensor.noise)
    rng = np.random.default_rng(35)
    q_opt = sensor.table.loc[rows_opt, list(sensor.joint_columns)].to_numpy(dtype=float)
    plan_eval = design.evaluation_configurations(chain, design.EVALUATION_CONFIGURATIONS, rng, within=q_opt)
    jc, je, prior = model.whitened_jacobian(q_opt), model.jacobian(plan_eval), model.prior_information()
    priors_of_discrepancy = {
        "robust": dd.workspace_discrepancy(plan_eval, sensor.noise),
        "robust_campaign_gp": campaign_discrepancy(chain, sensor, priors),
    }
    designs = {
        kind: dd.robust_design(jc, q_opt, je, plan_eval, prior, prior_d, sensor.noise, budget=max(grid))
        for kind, prior_d in priors_of_discrepancy.items()
    }
    # bench_planner's "planned (candidates' ranges)": the same evaluation configurations, the p95 criterion
    designs["workspace"] = design.greedy_design(jc, je, prior, budget=max(grid))
    position = pd.Series(np.arange(len(rows_opt)), index=rows_opt)
    rows = []
    for n in grid:
        for kind, chosen in designs.items():
            rms = validation_rms(chain, subset_sensor(sensor, rows_opt[chosen.chosen[:n]]), priors)
            rows.append(
                {
                    "design": kind,
                    "n": n,
                    "draw": 0,
                    "validation_rms_mm": rms,
                    **{
                        f"expected_rms_mm_{name}": expected_rms(
                            jc[chosen.chosen[:n]], q_opt[chosen.chosen[:n]], prior, je, plan_eval, d, sensor.noise
                        )
                        for name, d in priors_of_discrepancy.items()
                    },
                }
            )
            print(f"ur5 {kind} n={n}: {rms:.4f} mm", flush=True)
        for draw in range(draws):
            for kind, size in (("random", n), ("random_3n", 3 * n)):
                chosen = rng.choice(rows_opt, size=min(size, len(rows_opt)), replace=False)
                rms = validation_rms(chain, subset_sensor(sensor, chosen), priors)
                # what the robust criterion expects of these rows, under each discrepancy prior
                at = position[chosen]
                expected = {
                    f"expected_rms_mm_{name}": expected_rms(jc[at], q_opt[at], prior, je, plan_eval, d, sensor.noise)
                    for name, d in priors_of_discrepancy.items()
                }
                rows.append({"design": kind, "n": n, "draw": draw, "validation_rms_mm": rms, **expected})
                print(f"ur5 {kind} n={n} draw {draw}: {rms:.4f} mm", flush=True)
    table = pd.DataFrame(rows)
    median = table.groupby(["design", "n"])["validation_rms_mm"].median()
    predicted = table.groupby(["design", "n"])[[f"expected_rms_mm_{k}" for k in priors_of_discrepancy]].median()
    return {
        "campaign": "data/raw/jacobi-ur5-gts3800 (1000 optimization rows, 20 validation rows)",
        "draws": draws,
        "noise_mm": float(sensor.noise) / 1e-3,
        "all_1000_rows_validation_rms_mm": validation_rms(chain, sensor, priors),
        "discrepancy_priors": {k: v.report() for k, v in priors_of_discrepancy.items()},
        "rows": rows,
        "verdict": [
            {
                "n": n,
                "robust_mm": float(median[("robust", n)]),
                "robust_campaign_gp_mm": float(median[("robust_campaign_gp", n)]),
                "workspace_mm": float(median[("workspace", n)]),
                "random_n_median_mm": float(median[("random", n)]),
                "random_3n_median_mm": float(median[("random_3n", n)]),
                "reaches_3n_random": bool(median[("robust", n)] <= median[("random_3n", n)]),
                # the criterion's own expectation (default prior) of the robust rows, N and 3N random rows
                "expected_robust_mm": float(predicted.loc[("robust", n), "expected_rms_mm_robust"]),
                "expected_random_n_mm": float(predicted.loc[("random", n), "expected_rms_mm_robust"]),
                "expected_random_3n_mm": float(predicted.loc[("random_3n", n), "expected_rms_mm_robust"]),
                "expected_workspace_mm": float(predicted.loc[("workspace", n), "expected_rms_mm_robust"]),
                "expected_campaign_gp_robust_mm": float(
                    predicted.loc[("robust_campaign_gp", n), "expected_rms_mm_robust_campaign_gp"]
                ),
                "expected_campaign_gp_random_n_mm": float(
                    predicted.loc[("random", n), "expected_rms_mm_robust_campaign_gp"]
                ),
                "expected_campaign_gp_random_3n_mm": float(
                    predicted.loc[("random_3n", n), "expected_rms_mm_robust_campaign_gp"]
                ),
            }
            for n in grid
        ],
    }


def ur5_oracle(grid, draws: int = 25) -> dict:
    """How far can any choice of rows go? The UR5's optimization rows split in two (even rows the
    candidates, odd rows a held-out proxy; the validation rows are not read), the complete error model
    linearised at the registration (MAP of r = J theta under the priors, r the measured less the
    nominal positions, the stated noise), and rows chosen greedily by an ORACLE: each step adds the
    candidate that most lowers the RMS on the proxy rows, which no design can see. Beside it, N and 3N
    random candidates (median of `draws`). Where the oracle's N rows do not reach 3N random rows, no
    design of N rows is expected to (greedy is not the best subset, so this is evidence, not proof)."""
    campaign = folders.read_campaign(UR5, repo_root=REPO)
    chain, sensor = campaign.chain, campaign.sensors[SENSOR]
    rows = sensor.measured_rows("optimization")
    model = dp.complete_error_model(
        chain, sensor.marker, fit.register(chain, sensor).t_nr, config_priors(campaign.robot), sensor.noise
    )
    q = sensor.table.loc[rows, list(sensor.joint_columns)].to_numpy(dtype=float)
    measured = sensor.table.loc[rows, ["x", "y", "z"]].to_numpy(dtype=float)
    r = (measured - model.model(q).predict(np.zeros(len(model.names)))) / sensor.noise  # whitened
    jw = model.whitened_jacobian(q)
    n_params = jw.shape[2]
    prior = model.prior_information()
    candidates, proxy = np.arange(0, len(q), 2), np.arange(1, len(q), 2)
    j_proxy, r_proxy = jw[proxy].reshape(-1, n_params), r[proxy].ravel()

    def proxy_rms(information, moment) -> float:
        theta = np.linalg.solve(information, moment)
        return float(np.sqrt(np.mean((r_proxy - j_proxy @ theta) ** 2)) * sensor.noise / 1e-3)

    def of_rows(chosen) -> float:
        j = jw[chosen].reshape(-1, n_params)
        return proxy_rms(prior + j.T @ j, j.T @ r[chosen].ravel())

    rng = np.random.default_rng(135)
    random_n = {
        n: float(np.median([of_rows(rng.choice(candidates, n, replace=False)) for _ in range(draws)])) for n in grid
    }
    random_3n = {
        n: float(np.median([of_rows(rng.choice(candidates, 3 * n, replace=False)) for _ in range(draws)])) for n in grid
    }
    information, moment, left, oracle = prior.copy(), np.zeros(n_params), list(candidates), {}
    for step in range(1, max(grid) + 1):
        scores = [proxy_rms(information + jw[c].T @ jw[c], moment + jw[c].T @ r[c]) for c in left]
        best = left.pop(int(np.argmin(scores)))
        information, moment = information + jw[best].T @ jw[best], moment + jw[best].T @ r[best]
        if step in grid:
            oracle[step] = float(min(scores))
    return {
        "parameters": int(n_params),
        "candidates": int(len(candidates)),
        "proxy_rows": int(len(proxy)),
        "all_candidates_mm": of_rows(candidates),
        "rows": [
            {"n": n, "oracle_mm": oracle[n], "random_n_mm": random_n[n], "random_3n_mm": random_3n[n]} for n in grid
        ],
    }


def markdown(results: dict) -> str:
    sim, real = results["simulator"], results["ur5"]
    kinds = ("robust", "workspace", "d_optimal", "random", "paper")
    median = {(m["design"], m["n"]): m for m in sim["median"]}
    lines = [
        f"Measured {results['date']} by `benchmarks/bench_robust_design.py` ({results['seconds']:.0f} s).",
        "",
        f"Simulator ({sim['scenario']}): true error of the calibrated model across the workspace "
        f"({sim['evaluation_configurations']} random configurations), RMS per axis, median over {sim['repeats']} "
        f"designs, mm. All {sim['candidates_per_repeat']} candidates measured and fitted: "
        f"{sim['all_candidates_true_rms_mm']:.4f} mm (not a floor: the candidates are not spread as the workspace); "
        f"noise {sim['noise_mm']:.3f} mm.",
        "",
        "| N | " + " | ".join(kinds) + " | robust p95 | workspace p95 | random p95 |",
        "|---" * (len(kinds) + 4) + "|",
    ]
    for n in sorted({m["n"] for m in sim["median"]}):
        cells = [f"{median[(k, n)]['true_rms_mm']:.4f}" for k in kinds]
        cells += [f"{median[(k, n)]['true_p95_mm']:.4f}" for k in ("robust", "workspace", "random")]
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"UR5 grid: validation RMS per axis (mm) on the 20 validation rows; random: median (range) of {real['draws']} "
        "draws; "
        f"all 1000 rows: {real['all_1000_rows_validation_rms_mm']:.4f} mm; stated noise {real['noise_mm']:.3f} mm.",
        "",
        "| N | robust (default prior) | robust (the campaign's GP) | workspace (p95 criterion) | random N | random 3N "
        "| robust <= random 3N |",
        "|---|---|---|---|---|---|---|",
    ]
    spread = {}
    for r in real["rows"]:
        spread.setdefault((r["design"], r["n"]), []).append(r["validation_rms_mm"])
    for v in real["verdict"]:
        draws = {k: spread[(k, v["n"])] for k in ("random", "random_3n")}
        lines.append(
            f"| {v['n']} | {v['robust_mm']:.4f} | {v['robust_campaign_gp_mm']:.4f} | {v['workspace_mm']:.4f} | "
            f"{v['random_n_median_mm']:.4f} ({min(draws['random']):.4f}-{max(draws['random']):.4f}) | "
            f"{v['random_3n_median_mm']:.4f} ({min(draws['random_3n']):.4f}-{max(draws['random_3n']):.4f}) | "
            f"{'yes' if v['reaches_3n_random'] else 'no'} |"
        )
    lines += [
        "",
        "What the criterion itself expects (RMS per axis across the candidates' box, mm; random: median of the "
        "draws), under the default prior and under the campaign's GP:",
        "",
        "| N | default: robust | workspace | random N | random 3N | campaign's GP: robust | random N | random 3N |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for v in real["verdict"]:
        lines.append(
            f"| {v['n']} | {v['expected_robust_mm']:.4f} | {v['expected_workspace_mm']:.4f} | "
            f"{v['expected_random_n_mm']:.4f} | "
            f"{v['expected_random_3n_mm']:.4f} | {v['expected_campaign_gp_robust_mm']:.4f} | "
            f"{v['expected_campaign_gp_random_n_mm']:.4f} | {v['expected_campaign_gp_random_3n_mm']:.4f} |"
        )
    oracle = results["ur5_oracle"]
    lines += [
        "",
        f"How far can any choice of rows go? (`ur5_oracle`: the complete model linearised, {oracle['parameters']} "
        f"parameters; {oracle['candidates']} even optimization rows the candidates, {oracle['proxy_rows']} odd ones a "
        "held-out proxy, validation rows unread; an oracle that adds, each step, the row that most lowers the "
        f"proxy's RMS; all candidates: {oracle['all_candidates_mm']:.4f} mm.) Proxy RMS per axis, mm:",
        "",
        "| N | oracle (sees the proxy) | random N | random 3N | oracle <= random 3N |",
        "|---|---|---|---|---|",
    ]
    for row in oracle["rows"]:
        lines.append(
            f"| {row['n']} | {row['oracle_mm']:.4f} | {row['random_n_mm']:.4f} | {row['random_3n_mm']:.4f} | "
            f"{'yes' if row['oracle_mm'] <= row['random_3n_mm'] else 'no'} |"
        )
    priors = real["discrepancy_priors"]
    lines += [
        "",
        "Discrepancy priors on the UR5 (signal mm per axis; lengthscales deg): default "
        f"{priors['robust']['signal_std_mm']:.4f}, {fmt(priors['robust']['lengthscales_deg'])}; the campaign's GP "
        f"{priors['robust_campaign_gp']['signal_std_mm']:.4f}, {fmt(priors['robust_campaign_gp']['lengthscales_deg'])}.",
        "",
        *verdicts(results),
    ]
    return "\n".join(lines) + "\n"


def _ratios(pairs) -> str:
    values = [a / b for a, b in pairs]
    return f"{min(values):.2f}-{max(values):.2f} (median {float(np.median(values)):.2f})"


def verdicts(results: dict) -> list[str]:
    """The robust criterion against the others and the planner's UR5 target, in sentences computed from
    the results."""
    sim, real = results["simulator"], results["ur5"]
    rms = {(m["design"], m["n"]): m["true_rms_mm"] for m in sim["median"]}
    grid = sorted({m["n"] for m in sim["median"]})
    past_first = [n for n in grid if n > min(grid)]
    met = [v["n"] for v in real["verdict"] if v["reaches_3n_random"]]
    missed = [v["n"] for v in real["verdict"] if not v["reaches_3n_random"]]
    expected_met = [v["n"] for v in real["verdict"] if v["expected_robust_mm"] <= v["expected_random_3n_mm"]]
    expected_met_gp = [
        v["n"] for v in real["verdict"] if v["expected_campaign_gp_robust_mm"] <= v["expected_campaign_gp_random_3n_mm"]
    ]
    oracle = results["ur5_oracle"]["rows"]
    beaten = [r["n"] for r in oracle if r["oracle_mm"] > r["random_3n_mm"]]
    margins = [r["oracle_mm"] / r["random_3n_mm"] for r in oracle if r["oracle_mm"] <= r["random_3n_mm"]]
    return [
        f"- Simulator with a discrepancy the model lacks, true RMS per axis, N {past_first[0]}-{past_first[-1]}: "
        f"robust / workspace {_ratios((rms[('robust', n)], rms[('workspace', n)]) for n in past_first)}, "
        f"robust / D-optimal {_ratios((rms[('robust', n)], rms[('d_optimal', n)]) for n in past_first)}, "
        f"robust / random {_ratios((rms[('robust', n)], rms[('random', n)]) for n in past_first)}; at N {grid[0]} "
        f"robust / workspace {rms[('robust', grid[0])] / rms[('workspace', grid[0])]:.2f}.",
        f"- UR5 target with the robust criterion (default prior): N chosen rows reach the validation RMS of 3N random "
        f"rows at N = {', '.join(map(str, met)) or 'none'}, not at N = {', '.join(map(str, missed)) or 'none'}; "
        "robust / N random rows "
        f"{_ratios((v['robust_mm'], v['random_n_median_mm']) for v in real['verdict'])}, robust / the workspace "
        f"(p95) criterion {_ratios((v['robust_mm'], v['workspace_mm']) for v in real['verdict'])}, robust / 3N "
        f"random {_ratios((v['robust_mm'], v['random_3n_median_mm']) for v in real['verdict'])}.",
        "- The criterion's own expectation has the robust rows at or below 3N random rows at N = "
        f"{', '.join(map(str, expected_met)) or 'none'} (default prior), at N = "
        f"{', '.join(map(str, expected_met_gp)) or 'none'} (the campaign's GP), of "
        f"{', '.join(str(v['n']) for v in real['verdict'])}.",
        "- An oracle that chooses rows by their error on held-out optimization rows does not reach 3N random rows "
        f"at N = {', '.join(map(str, beaten)) or 'none'}"
        + (f"; where it does, by {1 - max(margins):.0%}-{1 - min(margins):.0%}." if margins else "."),
    ]


def document_blocks(results: dict) -> tuple[str, str]:
    """(docs/planning.md's block: robust_planner.md whole, README.md's: the UR5 target's verdict, short as
    the README is)."""
    return markdown(results), verdicts(results)[1] + "\n"


def publish(results: dict) -> None:
    """robust_planner.json's rendering: robust_planner.md and the documents' blocks."""
    (OUT / "robust_planner.md").write_text(markdown(results))
    for document, block in zip(DOCUMENTS, document_blocks(results)):
        document.write_text(with_block(document.read_text(), block, BEGIN, END))


def fmt(values) -> str:
    return "[" + ", ".join("none" if v is None else f"{v:.0f}" for v in values) + "]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="one repeat, N = 10 and 40 (a smoke run)")
    parser.add_argument("--only", choices=("simulator", "ur5"), help="run one part (the results file is not written)")
    parser.add_argument("--render", action="store_true", help="rewrite the markdown and documents from the json")
    args = parser.parse_args()
    if args.render:
        publish(json.loads((OUT / "robust_planner.json").read_text()))
        return
    started = time.time()
    results = {"date": time.strftime("%Y-%m-%d")}
    if args.only != "ur5":
        results["simulator"] = simulator(1, (10, 40)) if args.quick else simulator(REPEATS, SIM_N)
    if args.only != "simulator":
        results["ur5"] = ur5(1, (10, 40)) if args.quick else ur5(DRAWS, UR5_N)
        results["ur5_oracle"] = ur5_oracle((10, 40)) if args.quick else ur5_oracle(UR5_N)
    results["seconds"] = time.time() - started
    if args.quick or args.only:
        print(json.dumps({k: v for k, v in results.items() if k not in ("simulator", "ur5")}))
        return
    (OUT / "robust_planner.json").write_text(json.dumps(results, indent=1, default=float) + "\n")
    publish(results)
    print(markdown(results))


if __name__ == "__main__":
    main()
