"""Does every stated 95 % hold? The claims of a calibration against simulated truths it did not make,
over many seeds.

Small iiwa campaigns (25 configurations over 6 poses to fit, 16 to validate, a 10 um laser tracker)
go through the pipeline's own stages in-process (`truth_claims.check`: registration, the paper's
fit, the loop closure with config.yaml's settings, `remaster predict`, the workspace claims, the
acceptance test). Truths, each written by the simulator, not in the fit's parametrization:
zero-offsets only; rigid link errors (every fixed transform moved); cyclic joint errors; joint
compliance under a payload. Designs: joint 3 held (the iiwa planner's default) and every joint
turning. Per (truth, design, seed):

- near the data: the share of `remaster predict`'s commands (at the workspace claims' own
  configurations near the measured ones) whose true error exceeds their 95 % bound;
- the workspace claim near the data (the bound on one arm's p95) over the true p95 there, and
  whether it covers it (a 95 % bound: at least 95 % of the seeds); whether the claim across the
  joint limits is "not determined" (the priors decide it: with joint 3 held, it should be);
- the acceptance test's verdict (correct models: should fail at the level), and its check against the
  sensor's noise alone (`at_noise`: what a closed loop would claim);
- the loop closure's verdict (a test at `loop_closure/closure_level`: where the candidates hold the
  truth, not closed should be as rare as the level);
- the loop-closed zero-offset corrections, with their combined standard uncertainty;
- what the calibration's own posterior expects of the seed-level counts, each of its draws taken as
  the arm's truth (`truth_claims.own_posterior_expectations`): the chance of more than 25 % of the
  commands outside their bound, of the claim within 0.8-2 x the arm's p95, and of it covering it.

Then, per truth and seed, the corrections of the two designs of the same robot (same truth, other
poses): how often they differ by more than 3 combined standard uncertainties; and the acceptance
test's rejection rate on a model missing an effect present in both sets (compliance in the truth,
the loop without its compliance candidate).

--sbc: simulation-based calibration (Talts et al. 2018; Modrak et al. 2023) of the cells SBC_CELLS (truth,
design, sensor; campaigns measured by a laser tracker and a motion capture): per seed, the truth's normalized
rank among the calibration's posterior draws, each draw taken as the arm (`TruthCheck.ranks`: the mean PIT of
the commands' errors inside the measured ranges, across the limits, at the validation set; the registered
p95 inside the measured ranges; each estimated zero-offset); per cell and statistic, a Kolmogorov-Smirnov
test of the ranks against the uniform, their shares in the 2.5 % tails and their histogram; and each
zero-offset's z against the certificate's correction and U / k (posterior std, u_between, u_model) with the
share beyond its U. One cell withholds the truth's form from the loop's candidates (`WITHHELD`): there no
loop closes, and what the certificate's U holds of a model error is what its z tests. Writes
benchmarks/results/sbc.json (each campaign as it ends; a rerun adds only the campaigns it lacks) and sbc.md,
and the tables into docs/validation.md between its bench_sbc markers:
    .venv/bin/python benchmarks/bench_coverage.py --sbc [--seeds N] [--first SEED] [--cells I ...] [--draws K]
    [--n-random M] [--jobs J] [--render]
and, for one seed of the first of --cells, what lies behind its ranks (`sbc_why`: the zero-offsets' posterior
std and the parameter each follows, the noise estimated, the truth's raw and registered error against the
bounds), added to sbc.json and its text: ... --sbc --cells I --why SEED

Writes benchmarks/results/coverage.json and coverage.md, and the table into docs/validation.md
between its bench_coverage markers. Run from the repository root:
    .venv/bin/python benchmarks/bench_coverage.py [--seeds N] [--first SEED] [--jobs J] [--missing-seeds M]
    [--add-missing] (the missing-effect campaigns coverage.json lacks, added to it; --render: the tables only)
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from datetime import date
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import publish  # noqa: E402
from benchmarks.truth_claims import REPO, check  # noqa: E402
from remaster import configuration, files  # noqa: E402
from remaster.campaigns.arm_kinds import (  # noqa: E402
    MOTION_CAPTURE,
    TRACKER,
    chain_of,
    cyclic_truth,
    iiwa_scenario,
)
from remaster.robot import priors  # noqa: E402
from remaster.units import DEG, MM  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
VALIDATION_DOC = REPO / "docs" / "validation.md"
TRUTHS = {
    "zero-offsets": {},
    "rigid links": {"link_errors": {"translation_std": 1.0e-4, "rotation_std": 2.0e-4, "seed": 9}},
    "cyclic": {"cyclic_error": cyclic_truth()},
    "compliance": {
        "joint_compliance": [0.0, 2.5e-5, 0.0, 3.0e-5, 0.0, 5.0e-5, 0.0],
        "payload": {"mass": 2.5, "com": [0.0, 0.0, 0.03]},
    },
}
DESIGNS = {
    "q3 held": {},
    "every joint": {"q3": "free"},
    # four times the optimization set: enough configurations for a residual field's kernel
    "q3 held, 100 configurations": {
        "sets": {"optimization": {"poses": 20, "configurations": 100}, "validation": {"poses": 4, "configurations": 16}}
    },
}
# the candidate effects that express each truth: a loop that added them holds the truth's form
TRUTH_EFFECTS = {
    "zero-offsets": (),
    "rigid links": ("link_geometry",),
    "cyclic": ("joint_harmonics",),
    "compliance": ("joint_compliance",),
}
# SBC's own design (Talts et al. 2018): truths drawn per seed from the priors the fit uses, so that where the
# priors, not the data, decide (a joint held, the link geometry the zero-offsets trade with) a calibrated
# posterior still ranks its truth uniformly; every fixed transform moved by the configured class's link priors
# every fixed transform moved by the configured class's link priors; every joint's cyclic error drawn
# from the joint-harmonic prior at each order the loop offers
PRIOR_TRUTHS = {"rigid links from the prior": "link_errors", "cyclic from the prior": "cyclic_error"}
TRUTH_EFFECTS["rigid links from the prior"] = ("link_geometry",)
TRUTH_EFFECTS["cyclic from the prior"] = ("joint_harmonics",)
# a loop that cannot close: the truth's form withheld from its candidates, so that what the certificate's U
# holds of a model error (the residual field's share, methods.md) is what the ranks and z test
PRIOR_TRUTHS["cyclic from the prior, harmonics withheld"] = "cyclic_error"
TRUTH_EFFECTS["cyclic from the prior, harmonics withheld"] = ("joint_harmonics",)
WITHHELD = {"cyclic from the prior, harmonics withheld": ("joint_harmonics",)}
MISSING = ("compliance", ("joint_compliance",))  # the truth, and the candidates the loop is not offered
# simulation-based calibration (--sbc): (truth, design, sensor) in the order they run, on campaigns measured
# by the twin's two sensors (a 10 um laser tracker, a 30 um motion capture) so that a truth's two sensors see
# the same arm and poses
SBC_CELLS = (
    ("rigid links", "q3 held", "motion_capture"),
    ("rigid links", "q3 held", "laser_tracker"),
    ("cyclic", "q3 held", "laser_tracker"),
    ("rigid links from the prior", "q3 held", "motion_capture"),
    ("rigid links from the prior", "q3 held", "laser_tracker"),
    ("cyclic from the prior", "q3 held", "laser_tracker"),
    ("cyclic from the prior, harmonics withheld", "q3 held, 100 configurations", "laser_tracker"),
)
SBC_SENSORS = {"laser_tracker": dict(TRACKER), "motion_capture": dict(MOTION_CAPTURE)}
SBC_LEVEL, SBC_TAIL, SBC_BINS = 0.01, 0.025, 10


def truth_of(truth: str, seed: int) -> dict:
    """The scenario's truth block of a truth kind at one seed: fixed (`TRUTHS`), or drawn from the
    configured priors (`PRIOR_TRUTHS`): link errors of the default arm class's `link_translation_mm`
    and `link_rotation_deg`, from the simulator's own draw of the seed; or a cyclic error on every
    joint, its coefficients a_jk, b_jk (a cos k q + b sin k q, orders k = 1..loop_closure/harmonics/
    orders) each drawn from N(0, joint_harmonic_deg^2), written as the simulator's A sin(k q + phi)."""
    if truth not in PRIOR_TRUTHS:
        return TRUTHS[truth]
    config = configuration.settings(files.read_yaml(REPO / "config.yaml"))
    stds = priors.DEFAULTS[config["priors"]["arm_class"]] | config["priors"][config["priors"]["arm_class"]]
    if PRIOR_TRUTHS[truth] == "cyclic_error":
        rng = np.random.default_rng(2000 + seed)
        terms = []
        for order in range(1, config["loop_closure"]["harmonics"]["orders"] + 1):
            a, b = rng.normal(0.0, stds["joint_harmonic_deg"], (2, 7))
            terms.append(
                {
                    "amplitude_deg": np.hypot(a, b).tolist(),
                    "cycles_per_turn": [float(order)] * 7,
                    "phase_deg": np.degrees(np.arctan2(a, b)).tolist(),
                }
            )
        return {"cyclic_error": terms}
    return {
        "link_errors": {
            "translation_std": stds["link_translation_mm"] * MM,
            "rotation_std": stds["link_rotation_deg"] * DEG,
            "seed": 1000 + seed,
        }
    }


def one(task: tuple) -> dict:
    """The numbers of one (truth, design, seed, without) campaign."""
    truth, design, seed, without = task
    started = time.perf_counter()
    spec = iiwa_scenario(f"coverage-{seed}", seed=seed, truth=TRUTHS[truth], plan=DESIGNS[design])
    checked = check(spec, chain_of(spec, REPO), "laser_tracker", n_random=200, draws=400, seed=seed, without=without)
    claim = checked.claims["domain"]
    # the certificate's corrections and combined standard uncertainties (U / k), where it gives a U
    corrections = {
        f"zero_offsets.q{j + 1}": [float(row["correction_rad"]), float(row["U_deg"]) / float(row["k"]) * DEG]
        for j, row in checked.calibration.corrections().iterrows()
        if row["status"] == "estimated" and np.isfinite(row["U_deg"])
    }
    return {
        "truth": truth,
        "design": design,
        "seed": seed,
        "without": list(without),
        "effects": list(checked.effects),
        "closure": {
            k: (checked.report.closure or {}).get("rounds", [{}])[-1].get(k)
            for k in ("closed", "ratio_to_floor", "p_value")
        },
        "outside_share_near": 1.0 - checked.domain_held_fraction,
        "claim_over_true_p95_near": claim.p95_bound_mm / claim.true_p95_mm,
        "claim_determined_near": claim.determined,
        "claim_covers_near": claim.covers,
        "claim_determined_random": checked.claims["random"].determined,
        "acceptance": checked.acceptance.verdict,
        "acceptance_p": (checked.acceptance.checks.get("loop") or {}).get("p_value"),
        "acceptance_at_noise": ((checked.acceptance.checks.get("loop") or {}).get("at_noise") or {}).get("passed"),
        "seconds": time.perf_counter() - started,
        "corrections": corrections,
        "own_posterior": checked.own_posterior,
    }


def sbc_one(task: tuple) -> dict:
    """The truth's ranks among its calibration's posterior draws (`TruthCheck.ranks`) of one (truth,
    design, sensor, seed), with the seed-level counts beside them."""
    truth, design, sensor, seed, n_random, draws = task
    started = time.perf_counter()
    spec = iiwa_scenario(
        f"coverage-{seed}", seed=seed, truth=truth_of(truth, seed), plan=DESIGNS[design], sensors=SBC_SENSORS
    )
    checked = check(
        spec, chain_of(spec, REPO), sensor, n_random=n_random, draws=draws, seed=seed, without=WITHHELD.get(truth, ())
    )
    return {
        "truth": truth,
        "design": design,
        "sensor": sensor,
        "seed": seed,
        "effects": list(checked.effects),
        "ranks": checked.ranks,
        "outside_share_near": 1.0 - checked.domain_held_fraction,
        "outside_share_validation": 1.0 - checked.planned_held_fraction,
        "claim_covers_near": checked.claims["domain"].covers,
        "validation_over_noise": checked.validation_rms_per_axis_mm / checked.noise_mm,
        "declared_model_error_mm": (checked.report.declared_model_error("loop") or 0.0) / 1e-3,
        "own_posterior": checked.own_posterior,
        "seconds": time.perf_counter() - started,
    }


def sbc_why(task: tuple) -> dict:
    """What lies behind one campaign's ranks, measured (--why): each estimated zero-offset's
    posterior std and the parameter its draws follow most closely (the correlation, and whether the
    loop reports that one as decided by its prior); the noise the loop estimated against the
    sensor's; near the data, the truth's error (p95, raw in the sensor frame and registered: what a
    rigid motion does not explain) against the per-command bounds and the draws' registered p95."""
    truth, design, sensor, seed, n_random, draws = task
    spec = iiwa_scenario(
        f"coverage-{seed}", seed=seed, truth=truth_of(truth, seed), plan=DESIGNS[design], sensors=SBC_SENSORS
    )
    checked = check(
        spec, chain_of(spec, REPO), sensor, n_random=n_random, draws=draws, seed=seed, without=WITHHELD.get(truth, ())
    )
    report = checked.report
    samples = checked.samples.drop(columns=["log_prob", "chain", "walker", "step"], errors="ignore")
    correlation = samples.corr()
    zero = {}
    for name in (n for n in checked.ranks if n.startswith("zero_offsets.")):
        partners = correlation[name].drop(name).abs().nlargest(2).index
        zero[name] = {
            "rank": checked.ranks[name]["rank"],
            "std_deg": math.degrees(float(samples[name].std())),
            "partners": [[str(n), float(correlation.loc[name, n]), n in report.prior_dominated] for n in partners],
        }
    p95 = checked.ranks["p95_near"]
    return {
        "truth": truth,
        "design": design,
        "sensor": sensor,
        "seed": seed,
        "zero_offsets": zero,
        "prior_dominated": list(report.prior_dominated),
        "sigma_after_mm": float(report.sigma_after_mm),
        "sigma_posterior_mm": (np.quantile(samples["noise.sigma"], [0.05, 0.5, 0.95]) / 1e-3).tolist(),
        "noise_mm": checked.noise_mm,
        "outside_share_near": 1.0 - checked.domain_held_fraction,
        "near_error_p95_mm": float(np.quantile(checked.domain_error_mm, 0.95)),
        "near_bound_median_mm": float(np.median(checked.domain_bound_mm)),
        "near_registered_p95_mm": p95["truth"],
        "near_registered_p95_draws_median_mm": p95["draws_median"],
        "ranks": {k: v["rank"] for k, v in checked.ranks.items()},
        "gross_rows": list((report.gross_errors or {}).get("optimization", [])),
    }


def sbc_summary(runs: list[dict]) -> list[dict]:
    """Per (truth, design, sensor) and statistic: the ranks' Kolmogorov-Smirnov test against the
    uniform (p-value, rejected at SBC_LEVEL), their shares in either SBC_TAIL and their histogram;
    the same over the seeds whose loop added the effects that express the truth (`TRUTH_EFFECTS`:
    the model holds the truth's form, which the ranks' uniformity presumes)."""
    cells = []
    for truth, design, sensor in dict.fromkeys((r["truth"], r["design"], r["sensor"]) for r in runs):
        part = [r for r in runs if (r["truth"], r["design"], r["sensor"]) == (truth, design, sensor)]
        held = [r for r in part if set(TRUTH_EFFECTS[truth]) <= set(r["effects"])]
        outside = np.array([r["outside_share_near"] for r in part])
        cells.append(
            {
                "truth": truth,
                "design": design,
                "sensor": sensor,
                "seeds": len(part),
                "rows": _rank_rows(part),
                "held_seeds": len(held),
                "held_rows": _rank_rows(held) if 1 < len(held) < len(part) else [],
                "outside_mean": float(outside.mean()),
                "seeds_outside_above_25": int(np.sum(outside > 0.25)),
                "expected_outside_above_25": _expected(part, "outside_above_25"),
                "claim_covers": int(sum(r["claim_covers_near"] for r in part)),
                "certified": _certified(part, design),
                "seconds_per_campaign": float(np.median([r["seconds"] for r in part])),
            }
        )
    return cells


def _certified(part: list[dict], design: str) -> dict:
    """The zero-offsets whose certificate gives a U, pooled over a cell's seeds: how many, and the shares
    beyond that U and beyond 1.96 posterior stds; all of them, those of the joints the design turns and
    those of the joint it holds (where a joint error is a constant no fit can tell from the zero-offset)."""
    held = () if DESIGNS[design].get("q3") == "free" else ("zero_offsets.q3",)
    entries = [
        (name, v)
        for r in part
        for name, v in r["ranks"].items()
        if name.startswith("zero_offsets.") and "z_certified" in v
    ]
    out = {}
    for label, chosen in (
        ("all", entries),
        ("turned", [e for e in entries if e[0] not in held]),
        ("held", [e for e in entries if e[0] in held]),
    ):
        if chosen:
            out[label] = {
                "count": len(chosen),
                "beyond_U": float(np.mean([abs(v["z_certified"]) > v["k_certified"] for _, v in chosen])),
                "beyond_posterior": float(np.mean([abs(v["z"]) > 1.96 for _, v in chosen])),
            }
    return out


def _certified_line(certified: dict) -> list[str]:
    """`_certified` as a sentence (none where no certificate of the cell gives a U)."""
    if not certified:
        return []
    said = {"all": "all", "turned": "of the joints the design turns", "held": "of the joint it holds"}
    parts = [
        f"{said[k]} {v['count']}: {100 * v['beyond_U']:.0f} % beyond U ({100 * v['beyond_posterior']:.0f} % beyond "
        "1.96 posterior stds)"
        for k, v in certified.items()
    ]
    return ["", "Zero-offsets against the certificate's U (pooled over the seeds): " + "; ".join(parts) + "."]


def _rank_rows(part: list[dict]) -> list[dict]:
    """`sbc_summary`'s rows of one set of runs: one per statistic."""
    rows = []
    for name in dict.fromkeys(k for r in part for k in r["ranks"]):
        ranks = np.array([r["ranks"][name]["rank"] for r in part if name in r["ranks"]])
        p_value = float(stats.kstest(ranks, "uniform").pvalue)
        # a parameter's (truth - posterior mean) / posterior std over seeds: sd 1 where the data decide it
        z = np.array([r["ranks"][name]["z"] for r in part if "z" in r["ranks"].get(name, {})])
        # the same against the certificate's correction and U / k (its posterior std, u_between, u_model)
        certified = [r["ranks"][name] for r in part if "z_certified" in r["ranks"].get(name, {})]
        z_c = np.array([c["z_certified"] for c in certified])
        beyond_u = np.array([abs(c["z_certified"]) > c["k_certified"] for c in certified])
        rows.append(
            {
                "statistic": name,
                "seeds": int(ranks.size),
                "ks_p": p_value,
                "rejected": p_value < SBC_LEVEL,
                "below": float(np.mean(ranks < SBC_TAIL)),
                "above": float(np.mean(ranks > 1.0 - SBC_TAIL)),
                "histogram": np.histogram(ranks, SBC_BINS, (0.0, 1.0))[0].tolist(),
                "median_rank": float(np.median(ranks)),
                "z_mean": float(z.mean()) if z.size > 1 else None,
                "z_sd": float(z.std(ddof=1)) if z.size > 1 else None,
                "z_certified_sd": float(z_c.std(ddof=1)) if z_c.size > 1 else None,
                "beyond_certified_U": float(beyond_u.mean()) if z_c.size > 1 else None,
            }
        )
    return rows


def pairs(runs: list[dict]) -> list[float]:
    """|difference| / combined u of each zero-offset estimated in both designs of one truth and seed."""
    by = {(r["truth"], r["seed"], r["design"]): r for r in runs if not r["without"]}
    out = []
    for (truth, seed, design), run in by.items():
        if design != "q3 held" or (truth, seed, "every joint") not in by:
            continue
        other = by[(truth, seed, "every joint")]["corrections"]
        for name, (mean, u) in run["corrections"].items():
            if name in other:
                out.append(abs(mean - other[name][0]) / math.hypot(u, other[name][1]))
    return out


def summary(runs: list[dict]) -> dict:
    correct = [r for r in runs if not r["without"]]
    rows = []
    for truth in TRUTHS:
        for design in DESIGNS:
            part = [r for r in correct if r["truth"] == truth and r["design"] == design]
            if not part:
                continue
            outside = np.array([r["outside_share_near"] for r in part])
            # the certificate gives a number only where the data determine it ("not determined" else)
            ratio = np.array([r["claim_over_true_p95_near"] for r in part if r["claim_determined_near"]])
            covers = [r["claim_covers_near"] for r in part if r["claim_determined_near"] and "claim_covers_near" in r]
            rows.append(
                {
                    "truth": truth,
                    "design": design,
                    "seeds": len(part),
                    "outside_mean": float(outside.mean()),
                    "outside_max": float(outside.max()),
                    "claim_ratio_min": float(ratio.min()) if ratio.size else None,
                    "claim_ratio_max": float(ratio.max()) if ratio.size else None,
                    "claim_ratio_median": float(np.median(ratio)) if ratio.size else None,
                    "claim_covers": int(sum(covers)),
                    "not_determined_across_limits": int(sum(not r.get("claim_determined_random", True) for r in part)),
                    "not_determined": len(part) - int(ratio.size),
                    "acceptance_failed": int(sum(r["acceptance"] == "fail" for r in part)),
                    "not_closed": int(sum(r["closure"]["closed"] is False for r in part)),
                    "in_window": int(sum(0.8 <= x <= 2.0 for x in ratio)),
                    "expected_in_window": _expected([r for r in part if r["claim_determined_near"]], "claim_in_window"),
                }
            )
    z = np.array(pairs(runs))
    missing = [r for r in runs if r["without"]]
    determined = [r for r in correct if r["claim_determined_near"] and "claim_covers_near" in r]
    return {
        "rows": rows,
        "corrections_pairs": int(z.size),
        "corrections_beyond_3u": float(np.mean(z > 3.0)) if z.size else None,
        "missing_effect_runs": len(missing),
        "missing_effect_rejected": float(np.mean([r["acceptance"] == "fail" for r in missing])) if missing else None,
        "missing_effect_rejected_at_noise": float(np.mean([r["acceptance_at_noise"] is False for r in missing]))
        if missing
        else None,
        "correct_rejected_at_noise": float(np.mean([r["acceptance_at_noise"] is False for r in correct])),
        # the closure test (level `loop_closure/closure_level`): where the loop added what expresses the truth, and not
        **_closure_rates(correct, missing),
        "claims_determined": len(determined),
        "claims_covering": int(sum(r["claim_covers_near"] for r in determined)),
        "claims_in_window": int(sum(0.8 <= r["claim_over_true_p95_near"] <= 2.0 for r in determined)),
        "claims_above_window": int(sum(r["claim_over_true_p95_near"] > 2.0 for r in determined)),
        "seeds_outside_above_25": int(sum(r["outside_share_near"] > 0.25 for r in correct)),
        # what each calibration's own posterior expects of these seed-level counts (`own_posterior`)
        "expected_outside_above_25": _expected(correct, "outside_above_25"),
        "expected_in_window": _expected(determined, "claim_in_window"),
        "expected_covering": _expected(determined, "claim_covers"),
        "seconds_per_campaign": float(np.median([r["seconds"] for r in runs])),
    }


def _rate(share: float, runs: int) -> str:
    """'k of n (x %; one-sided 95 % lower bound y %)', the bound Clopper-Pearson's."""
    k = round(share * runs)
    lower = stats.beta.ppf(0.05, k, runs - k + 1) if k > 0 else 0.0
    return f"{k} of {runs} ({100 * share:.0f} %; one-sided 95 % lower bound {100 * lower:.1f} %)"


def _holds_truth(run: dict) -> bool:
    """Whether the loop added every candidate effect that expresses the run's truth (`TRUTH_EFFECTS`)."""
    return not run["without"] and set(TRUTH_EFFECTS[run["truth"]]) <= set(run["effects"])


def _closure_rates(correct: list[dict], missing: list[dict]) -> dict:
    """How often the closure test said "not closed" where the loop's model holds the truth's form
    (its level, if the test is what it says) and where it does not (its power)."""
    held = [r for r in correct if _holds_truth(r)]
    lacking = [r for r in correct if not _holds_truth(r)] + list(missing)
    return {
        "held_truth_runs": len(held),
        "held_truth_not_closed": int(sum(r["closure"]["closed"] is False for r in held)),
        "held_truth_not_closed_cases": [
            f"{r['truth']}, {r['design']}, seed {r['seed']}: p = {r['closure'].get('p_value', float('nan')):.2g}"
            for r in held
            if r["closure"]["closed"] is False
        ],
        "lacking_truth_runs": len(lacking),
        "lacking_truth_not_closed": int(sum(r["closure"]["closed"] is False for r in lacking)),
    }


def _binomial_interval(k: int, runs: int) -> str:
    """'95 % interval a-b %' of a rate seen k times in runs (Clopper-Pearson)."""
    low = stats.beta.ppf(0.025, k, runs - k + 1) if k > 0 else 0.0
    high = stats.beta.ppf(0.975, k + 1, runs - k) if k < runs else 1.0
    return f"95 % interval {100 * low:.1f}-{100 * high:.1f} %"


def _below_expected(seen: int, expected: float, runs: int) -> bool:
    """Whether a count is more than two binomial standard deviations below what was expected of it."""
    share = expected / runs
    return seen < expected - 2.0 * math.sqrt(runs * share * (1.0 - share))


def _expected(runs: list[dict], key: str) -> float | None:
    """The count the runs' own posteriors expect: the sum of each run's chance (None if not recorded)."""
    chances = [(r.get("own_posterior") or {}).get(key) for r in runs]
    return None if not chances or None in chances else float(sum(chances))


def markdown(record: dict) -> str:
    s = record["summary"]
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_coverage.py` ({record['seeds']} seeds from {record['first']}; "
        "small iiwa campaigns, a 10 um laser tracker):",
        "",
        "| truth | design | seeds | commands outside their bound near the data: mean | max | claim near the data "
        "not determined (the priors decide) | claim / true p95 where determined: min | median | max | claim covers "
        "the true p95 | claim across the limits not determined | acceptance failed | claim within 0.8-2 x the "
        "true p95: seen / its posteriors expect | loop not closed |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in s["rows"]:
        determined = r["seeds"] - r["not_determined"]
        ratios = (
            f"{r['claim_ratio_min']:.2f} | {r['claim_ratio_median']:.2f} | {r['claim_ratio_max']:.2f}"
            if r["claim_ratio_min"] is not None
            else "- | - | -"
        )
        lines.append(
            f"| {r['truth']} | {r['design']} | {r['seeds']} | {100 * r['outside_mean']:.1f} % | "
            f"{100 * r['outside_max']:.0f} % | {r['not_determined']} of {r['seeds']} | {ratios} | "
            f"{r['claim_covers']} of {determined} | {r['not_determined_across_limits']} of {r['seeds']} | "
            f"{r['acceptance_failed']} of {r['seeds']} | "
            + (
                f"{r['in_window']} / {r['expected_in_window']:.1f} |"
                if r.get("expected_in_window") is not None
                else "- |"
            )
            + f" {r.get('not_closed', '-')} of {r['seeds']} |"
        )
    beyond = s["corrections_beyond_3u"]
    rejected = s["missing_effect_rejected"]
    lines += [
        "",
        f"Zero-offset corrections of the two designs of one robot: {s['corrections_pairs']} pairs, "
        + (
            f"{100 * beyond:.1f} % differ by more than 3 combined standard uncertainties."
            if beyond is not None
            else "none."
        ),
        "A model missing an effect present in both sets (compliance, the loop not offered it): the acceptance test "
        + (
            f"failed {100 * rejected:.0f} % of {s['missing_effect_runs']} campaigns against the model error the "
            f"loop declared, {_rate(s['missing_effect_rejected_at_noise'], s['missing_effect_runs'])} against what "
            "a closed loop would claim (the sensor's noise alone, the posterior's spread at that noise)."
            if rejected is not None
            else "not run."
        ),
        f"Every other campaign above (the loop offered every candidate): the test against the noise alone failed "
        f"{100 * s['correct_rejected_at_noise']:.0f} % (those whose loop did not close declare their residual "
        "and fail it, rightly).",
    ]
    if "held_truth_runs" in s:
        lines.append(
            "The closure test (level 1 %): where the loop added the effects that express the truth (none for "
            "zero-offsets, link geometry, joint harmonics, joint compliance), not closed on "
            f"{s['held_truth_not_closed']} of {s['held_truth_runs']} campaigns "
            f"({_binomial_interval(s['held_truth_not_closed'], s['held_truth_runs'])}"
            + (f": {'; '.join(s['held_truth_not_closed_cases'])}" if s["held_truth_not_closed"] else "")
            + f"); where it did not (the missing-effect campaigns included), on {s['lacking_truth_not_closed']} of "
            f"{s['lacking_truth_runs']}."
        )
    if s.get("claims_determined"):
        n = s["claims_determined"]
        own = s.get("expected_in_window") is not None and s.get("expected_outside_above_25") is not None
        lines += [
            f"The workspace claim near the data (a 95 % bound on one arm's p95) covered the true p95 on "
            f"{s['claims_covering']} of {n} campaigns ({100 * s['claims_covering'] / n:.0f} %); it was within "
            f"0.8-2 times it on {s['claims_in_window']} ({100 * s['claims_in_window'] / n:.0f} %)"
            + (
                f"; each calibration's own posterior (its draws taken as the arm) expects {s['expected_covering']:.0f} "
                f"covering and {s['expected_in_window']:.0f} within the window; above twice the true p95 on "
                f"{s['claims_above_window']}"
                + (
                    ": the truths lie nearer the posterior mean than its draws do more often than the posteriors "
                    "expect (per truth in the table's last column)"
                    if _below_expected(s["claims_in_window"], s["expected_in_window"], n)
                    else " (per truth in the table's last column)"
                )
                if own
                else ""
            )
            + ". A bound that covers 95 % of arms lies above a typical arm's p95 by a margin that changes from "
            "seed to seed with the posterior's shape, so no honest bound falls in a fixed window on every seed.",
            f"Seeds whose share of commands outside their bound exceeded 25 %: {s['seeds_outside_above_25']} of "
            f"{sum(r['seeds'] for r in s['rows'])}"
            + (f" (their own posteriors expect {s['expected_outside_above_25']:.1f})" if own else "")
            + ": the errors of one arm are correlated across its commands, and an arm in the posterior's tail "
            "exceeds many bounds at once.",
        ]
    return "\n".join(lines)


SBC_LABELS = {
    "pit_near": "mean PIT over the commands inside the measured ranges (near the data)",
    "pit_across": "mean PIT over the commands across the joint limits",
    "pit_validation": "mean PIT over the validation set's commands",
    "p95_near": "the arm's registered p95 inside the measured ranges (what the workspace claim bounds)",
}


def sbc_markdown(record: dict) -> str:
    """The rank tests of every cell: a table each, the histograms as counts per tenth of [0, 1]."""
    lines = [
        f"Measured {record['date']} by `benchmarks/bench_coverage.py --sbc` (seeds from {record['first']}; small "
        f"iiwa campaigns measured by a 10 um laser tracker and a 30 um motion capture; {record['draws']} posterior "
        f"draws, {record['n_random']} commands per domain). The truth's rank among the calibration's posterior "
        "draws, each draw taken as the arm's truth (`TruthCheck.ranks`): uniform over seeds if the posterior is "
        f"calibrated; Kolmogorov-Smirnov against the uniform at {100 * SBC_LEVEL:.0f} %, and the shares of ranks "
        f"below {SBC_TAIL} and above {1 - SBC_TAIL} ({100 * SBC_TAIL:.1f} % each expected). A rank near 0: the "
        "truth lies nearer the prediction than the draws do (the posterior too wide); near 1: farther (too narrow, "
        "or off). The truths are fixed per truth kind and the seeds vary the poses and the noise, so where the "
        "priors decide (across the limits with joint 3 held) the ranks say how the priors' spread compares with "
        "this one truth, not whether the posterior is calibrated.",
    ]
    for cell in record["cells"]:
        expected = cell["expected_outside_above_25"]
        lines += [
            "",
            f"**{cell['truth']}, {cell['design']}, {cell['sensor'].replace('_', ' ')}** ({cell['seeds']} seeds; "
            f"commands outside their bound near the data: {100 * cell['outside_mean']:.1f} % on average, above 25 % "
            f"on {cell['seeds_outside_above_25']} seed{'' if cell['seeds_outside_above_25'] == 1 else 's'}"
            + (f", its own posteriors expect {expected:.1f}" if expected is not None else "")
            + f"; the claim near the data covers the true p95 on {cell['claim_covers']}):",
            "",
            *_rank_table(cell["rows"]),
            *_certified_line(cell.get("certified", {})),
        ]
        if cell.get("held_rows"):
            lines += [
                "",
                f"The {cell['held_seeds']} of these seeds whose loop added the effects that express the truth "
                f"({', '.join(TRUTH_EFFECTS[cell['truth']])}; on the others the model lacks the truth's form, and a loop "
                "that did not close declares a model error, in every draw: per command, or one field across them where "
                "the loop fitted a kernel to the residual):",
                "",
                *_rank_table(cell["held_rows"]),
            ]
    for why in record.get("why", []):
        lines += ["", _why_text(why)]
    return "\n".join(lines)


def _rank_table(rows: list[dict]) -> list[str]:
    """The markdown table of `_rank_rows`."""
    lines = [
        "| statistic | seeds | KS p | uniform at 1 % | ranks < 0.025 | ranks > 0.975 | median rank | "
        "histogram (tenths of [0, 1]) | z over seeds: mean, sd | against the certificate's U: z sd, beyond U |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        label = SBC_LABELS.get(r["statistic"], r["statistic"].replace("zero_offsets.", "zero-offset "))
        lines.append(
            f"| {label} | {r['seeds']} | {r['ks_p']:.2g} | {'rejected' if r['rejected'] else 'not rejected'} | "
            f"{100 * r['below']:.0f} % | {100 * r['above']:.0f} % | {r['median_rank']:.2f} | "
            f"{' '.join(str(c) for c in r['histogram'])} | "
            + (f"{r['z_mean']:.2f}, {r['z_sd']:.2f} |" if r.get("z_sd") is not None else "- |")
            + (
                f" {r['z_certified_sd']:.2f}, {100 * r['beyond_certified_U']:.0f} % |"
                if r.get("z_certified_sd") is not None
                else " - |"
            )
        )
    return lines


def _why_text(why: dict) -> str:
    """One --why campaign's measurements as a sentence."""
    zero = "; ".join(
        f"{name.split('.')[-1]}: rank {z['rank']:.2f}, std {z['std_deg']:.3g} deg, follows "
        + " and ".join(f"{n} (r = {r:.2f}{', prior-dominated' if prior else ''})" for n, r, prior in z["partners"])
        for name, z in why["zero_offsets"].items()
    )
    sigma = why["sigma_posterior_mm"]
    return (
        f"Measured (`--why {why['seed']}`), {why['truth']}, {why['design']}, {why['sensor'].replace('_', ' ')}, "
        f"seed {why['seed']}: noise per axis {why['sigma_after_mm'] * 1e3:.1f} um at the loop's fit, its posterior "
        f"{sigma[1] * 1e3:.1f} um (90 % {sigma[0] * 1e3:.1f}-{sigma[2] * 1e3:.1f}), against the sensor's "
        f"{why['noise_mm'] * 1e3:.0f} um; near the data {100 * why['outside_share_near']:.0f} % of the commands "
        f"outside their bound, the truth's error p95 {why['near_error_p95_mm'] * 1e3:.0f} um in the sensor frame "
        f"and {why['near_registered_p95_mm'] * 1e3:.0f} um registered, against a median bound of "
        f"{why['near_bound_median_mm'] * 1e3:.0f} um and a registered p95 of "
        f"{why['near_registered_p95_draws_median_mm'] * 1e3:.0f} um for the median draw (ranks: "
        + ", ".join(f"{k} {v:.3f}" for k, v in why["ranks"].items() if not k.startswith("zero_offsets."))
        + f"); zero-offsets: {zero}; the loop reports as prior-dominated: {', '.join(why['prior_dominated']) or 'none'}."
    )


def sbc(args) -> None:
    """Run (or, with --render, rewrite from sbc.json) the simulation-based calibration's cells, each
    campaign added to sbc.json as it ends, those it holds already not run again."""
    path = RESULTS / "sbc.json"
    record = json.loads(path.read_text(encoding="utf-8")) if path.exists() else {"runs": []}
    if args.why is not None:
        cell = SBC_CELLS[(args.cells or [0])[0]]
        why = sbc_why((*cell, args.why, args.n_random, args.draws))
        record["why"] = [
            w for w in record.get("why", []) if (w["truth"], w["design"], w["sensor"], w["seed"]) != (*cell, args.why)
        ]
        record["why"].append(why)
        path.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    elif not args.render:
        record.update(date=date.today().isoformat(), first=args.first, draws=args.draws, n_random=args.n_random)
        done = {(r["truth"], r["design"], r["sensor"], r["seed"]) for r in record["runs"]}
        cells = [SBC_CELLS[i] for i in args.cells] if args.cells else SBC_CELLS
        seeds = range(args.first, args.first + args.seeds)
        tasks = [(*c, s, args.n_random, args.draws) for c in cells for s in seeds if (*c, s) not in done]
        with ProcessPoolExecutor(args.jobs) as pool:
            for run in pool.map(sbc_one, tasks):
                record["runs"].append(run)
                path.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
                ranks = ", ".join(f"{k} {v['rank']:.2f}" for k, v in run["ranks"].items())
                print(f"{run['truth']}, {run['design']}, {run['sensor']}, seed {run['seed']}: {ranks}", flush=True)
    record["cells"] = sbc_summary(record["runs"])
    publish(RESULTS, "sbc", record, sbc_markdown(record), VALIDATION_DOC)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first", type=int, default=100)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument(
        "--missing-seeds", type=int, default=None, help="seeds of the missing-effect campaigns (default: --seeds)"
    )
    parser.add_argument("--truths", nargs="+", default=list(TRUTHS))
    parser.add_argument("--render", action="store_true", help="rewrite the tables from coverage.json, run nothing")
    parser.add_argument(
        "--add-missing",
        action="store_true",
        help="run only the missing-effect campaigns coverage.json lacks (up to --missing-seeds) and add them to it",
    )
    parser.add_argument("--sbc", action="store_true", help="simulation-based calibration of SBC_CELLS (sbc.json)")
    parser.add_argument("--cells", type=int, nargs="+", default=None, help="--sbc: which of SBC_CELLS (indices)")
    parser.add_argument("--draws", type=int, default=400, help="--sbc: posterior draws per statistic")
    parser.add_argument("--n-random", type=int, default=200, help="--sbc: commands per domain")
    parser.add_argument(
        "--why", type=int, default=None, help="--sbc: measure what lies behind the ranks of this seed (first --cells)"
    )
    args = parser.parse_args()
    if args.sbc:
        sbc(args)
        return
    earlier = (
        json.loads((RESULTS / "coverage.json").read_text(encoding="utf-8")) if args.render or args.add_missing else None
    )
    if args.render:
        earlier["summary"] = summary(earlier["runs"])
        write(earlier)
        return
    seeds = range(args.first, args.first + args.seeds)
    tasks = [] if args.add_missing else [(t, d, s, ()) for t in args.truths for d in DESIGNS for s in seeds]
    if MISSING[0] in args.truths:
        missing = range(args.first, args.first + (args.missing_seeds or args.seeds))
        tasks += [(MISSING[0], "every joint", s, MISSING[1]) for s in missing]
    if args.add_missing:
        done = {(r["truth"], r["design"], r["seed"], tuple(r["without"])) for r in earlier["runs"]}
        tasks = [t for t in tasks if t not in done]
    with ProcessPoolExecutor(args.jobs) as pool:
        runs = list(earlier["runs"]) if args.add_missing else []
        for run in pool.map(one, tasks):
            runs.append(run)
            print(
                f"{run['truth']:13s} {run['design']:12s} seed {run['seed']}{' without ' + ','.join(run['without']) if run['without'] else ''}: "
                f"outside {100 * run['outside_share_near']:5.1f} %, claim/true {run['claim_over_true_p95_near']:.2f}, "
                f"acceptance {run['acceptance']} (p {run['acceptance_p']}), effects {run['effects']}",
                flush=True,
            )
    record = {
        "date": earlier["date"] if args.add_missing else date.today().isoformat(),
        "seeds": earlier["seeds"] if args.add_missing else args.seeds,
        "first": earlier["first"] if args.add_missing else args.first,
        "runs": runs,
    }
    record["summary"] = summary(runs)
    write(record)


def write(record: dict) -> None:
    """coverage.json, coverage.md and the table in docs/validation.md."""
    publish(RESULTS, "coverage", record, markdown(record), VALIDATION_DOC)


if __name__ == "__main__":
    main()
