"""The selected model refitted by MCMC (`remaster.loop.loop_closure`, step 3), and its parameter table:
every parameter with its uncertainty, and which ones the data barely moved from their prior.

SI inside; the tables give display units (mm, deg) beside SI.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..inference import evidence, gauge, metrics
from ..inference.model import SIGMA
from ..inference.posterior_sampling import converged, converged_ensemble, sampler_diagnostics
from ..inference.posterior_summary import moments
from ..inference.posterior_targets import PosteriorTarget, SigmaMarginalTarget
from ..inference.sampling.chains import run_chains, run_emcee
from ..inference.sampling.independence import RidgeProposal, metropolis_independence
from ..inference.sampling.target import Chain
from ..units import DEG, MM
from .fitted import Fitted
from .settings import LoopSettings

# The refit's Student-t proposal: a t in P dimensions is a Gaussian whose scale varies by a factor
# sqrt(chi2_dof / dof) shared by all P coordinates, so with few degrees of freedom most draws land
# at the wrong radius (log-weights spread by ~P / sqrt(2 dof) nats); dof ~ 4 P keeps that spread
# near 1 nat and the tails still heavier than a Gaussian posterior's.
PROPOSAL_DOF_PER_PARAMETER = 4
PROPOSAL_INFLATION = 1.1
# posterior std / prior std above this: the data barely moved the parameter from its prior
PRIOR_DOMINATED = 0.5
# the share of a parameter's posterior variance the priors set (its own and those of the parameters
# it trades against) above this: more the priors' than the data's, even where its own prior is wide
PRIOR_SHARE = 0.5
# a parameter's weight in a determined combination below this share of the largest is left out
COMBINATION_PART = 0.1
COMBINATION_TERMS = 4  # at most this many parameters named beside the prior-dominated one


MIN_WALKERS = 32  # the ensemble's walkers: at least this, and 2 P + 2 for P parameters


def _diagnosed(chains, started: float, criteria) -> tuple[dict, bool]:
    """(sampler diagnostics of chains in the model's own parameters, whether they meet the criteria)."""
    report = sampler_diagnostics(chains, time.perf_counter() - started)
    return report, converged(report, criteria["max_rhat"], criteria["min_ess"])


def _attempt(sampler: str, run: dict, report: dict, done: bool) -> dict:
    return {
        "sampler": sampler,
        **{k: int(v) for k, v in run.items() if k in ("samples", "burn_in", "walkers", "chains")},
        "max_rhat": report["max_rhat"],
        "min_ess": report["min_ess"],
        "acceptance_rate": report["acceptance_rate"],
        "seconds": report["seconds"],
        "converged": done,
    }


def _ensemble(mode: evidence.PosteriorMode, folds, run: dict, criteria, rng: np.random.Generator):
    """emcee on the joint posterior (sigma included) in the refit's folded coordinates, from the
    mode's Laplace ball (`refit`'s fallback): (chains in the model's parameters, diagnostics,
    converged, the attempt's record)."""
    started = time.perf_counter()
    joint = PosteriorTarget(mode.model)
    centre, spread = np.append(mode.theta, mode.sigma), np.sqrt(np.diag(mode.covariance))
    back = None
    if folds is not None:
        back = gauge.Gauge(folds.folds, joint.names)
        centre, folded_covariance = back.laplace(centre, mode.covariance, joint.scale)
        joint, spread = gauge.FoldedTarget(joint, back), np.sqrt(np.diag(folded_covariance))
    walkers = max(MIN_WALKERS, 2 * len(centre) + 2)
    # the ensemble starts in the Laplace ball and must first spread along the ridges: a burn-in
    # as long as the first run's samples (with the first run's 500 steps it was still drifting
    # and the doublings could not wash that out: 24,500 steps on the twin, against 4,000 now)
    steps, burn_in = 2 * int(run["samples"]), int(run["samples"])
    ensemble = run_emcee(
        joint,
        rng,
        centre,
        spread,
        n_walkers=walkers,
        n_steps=steps,
        burn_in=burn_in,
        enough=converged_ensemble(joint.names, criteria),
        max_doublings=int(criteria["max_doublings"]),
    )
    chains = [ensemble if back is None else back.back(ensemble)]
    report, done = _diagnosed(chains, started, criteria)
    kept = (steps - burn_in) * 2 ** ensemble.settings["doublings"]
    attempt = _attempt("emcee", {"samples": burn_in + kept, "burn_in": burn_in, "walkers": walkers}, report, done)
    return chains, report, done, attempt


def refit(mode: evidence.PosteriorMode, settings: LoopSettings, rng: np.random.Generator) -> tuple[list[Chain], dict]:
    """Chains of the model's posterior by independence Metropolis (`metropolis_independence`)
    over the model's parameters with sigma integrated out (`posterior_targets.SigmaMarginalTarget`; sigma is
    then drawn exactly for each sample), in the coordinates where the Laplace approximation fits
    best (`gauge.sampling_coordinates`: the model's exact symmetries folded out), from a proposal
    that follows the valleys along which the posterior leaves that approximation
    (`RidgeProposal`; a Student-t when there is none), its kept steps doubled until the
    criteria hold (every R-hat <= max_rhat and every ESS >= min_ess), at most max_doublings times.
    When they still miss, emcee's ensemble (2 P + 2 walkers, at least
    MIN_WALKERS) runs on the joint posterior from the same mode, a burn-in as long as the first
    run, then as many steps again, doubled until the criteria hold, at most max_doublings times.
    Returns the chains, in the model's own parameters, and a JSON-ready report: the last run's
    diagnostics, every attempt (with its sampler), the coordinates, the bent directions, and
    `converged`."""
    marginal = SigmaMarginalTarget(mode.model)
    target, mean, covariance, folds, coordinates = gauge.sampling_coordinates(
        marginal, mode.model, mode.theta, mode.covariance[:-1, :-1], rng
    )
    run, criteria = dict(settings.mcmc), settings.convergence
    attempts = []
    started = time.perf_counter()
    dof = PROPOSAL_DOF_PER_PARAMETER * len(mean)
    proposal = RidgeProposal.fit(target, mean, covariance, dof, PROPOSAL_INFLATION)
    coordinates["bent"] = [] if proposal is None else proposal.report(target.names)
    # proposals are independent of the state, so a longer run is a fresh one: doubled until the
    # criteria hold, as the ensemble's is, at most max_doublings times
    for doubling in range(int(criteria["max_doublings"]) + 1):
        length = {**run, "samples": int(run["burn_in"]) + (int(run["samples"]) - int(run["burn_in"])) * 2**doubling}
        chains = run_chains(
            metropolis_independence,
            target,
            rng,
            int(run["chains"]),
            mean,
            mean=mean,
            covariance=covariance,
            n_samples=length["samples"],
            burn_in=int(run["burn_in"]),
            dof=dof,
            inflation=PROPOSAL_INFLATION,
            proposal=proposal,
        )
        chains = [marginal.with_sigma(c if folds is None else folds.back(c), rng) for c in chains]
        report, done = _diagnosed(chains, started, criteria)
        attempts.append(_attempt("metropolis_independence", length, report, done))
        if done:
            break
    if not done:
        # the proposal is too far from the posterior for an independence sampler: an ensemble
        # follows the posterior's shape, from the same mode, run on until the criteria hold
        chains, report, done, attempt = _ensemble(mode, folds, run, criteria, rng)
        attempts.append(attempt)
    return chains, {
        **report,
        "converged": done,
        "attempts": attempts,
        "coordinates": coordinates,
        "criteria": {"max_rhat": criteria["max_rhat"], "min_ess": criteria["min_ess"]},
    }


def parameter_table(fitted: Fitted, samples: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per parameter (held ones included) and sigma: mean, std and 95 % interval in SI and in
    display units, prior std, the posterior / prior std ratio, status, and why the data cannot see
    it (`unseen_by_data`: kept under its prior, or held without one). From the MCMC samples when
    given, else the Laplace approximation (mean = mode, interval mode +- 1.96 std)."""
    model = fitted.model
    names = list(model.names) + [SIGMA]
    if samples is not None:
        summary = moments(samples[names])
        mean, std, low, high = (summary[c].to_numpy() for c in ("mean", "std", "q2.5", "q97.5"))
        source = "MCMC (the refit's samples)"
    else:
        mean = np.append(fitted.theta, fitted.mode.sigma)
        std = np.append(fitted.mode.std, fitted.mode.sigma_std)
        low, high = mean - metrics.Z95 * std, mean + metrics.Z95 * std
        source = "posterior mode + Laplace"
    free = {n: (m, s, lo, hi) for n, m, s, lo, hi in zip(names, mean, std, low, high)}
    covariance = (
        np.cov(samples[list(model.names)].to_numpy(), rowvar=False) if samples is not None else fitted.mode.covariance
    )
    covariance = np.atleast_2d(covariance)[: len(model.names), : len(model.names)]
    prior = dict(zip(model.names, model.prior_std))
    shares = dict(zip(model.names, prior_shares(covariance, model.prior_std)))
    reasons = {
        **{n: "held: not identifiable" for n in model.fixed},
        **{n: f"held: {why}" for n, why in fitted.reduction.dropped.items() if n in model.fixed},
    }
    rows = []
    for name, scale, unit in list(zip(model.all_names, model.all_scale, model.all_unit)) + [(SIGMA, MM, "mm")]:
        m, s, lo, hi = free.get(name, (model.fixed.get(name, 0.0), np.nan, np.nan, np.nan))
        tau = prior.get(name, np.inf)
        ratio = s / tau if np.isfinite(tau) and np.isfinite(s) else np.nan
        share = shares.get(name, np.nan)
        dominated = bool(ratio > PRIOR_DOMINATED or share > PRIOR_SHARE)
        rows.append(
            {
                "parameter": name,
                "block": model.block_of.get(name, "noise"),
                "mean": m,
                "std": s,
                "q2.5": lo,
                "q97.5": hi,
                "unit": unit,
                "mean_display": m / scale,
                "std_display": s / scale,
                "q2.5_display": lo / scale,
                "q97.5_display": hi / scale,
                "prior_std_display": tau / scale if np.isfinite(tau) else np.nan,
                "posterior_to_prior_std": ratio,
                "prior_share": share,
                "prior_dominated": dominated,
                "determined_combination": (
                    determined_combination(name, model.names, covariance, dict(zip(model.all_names, model.all_scale)))
                    if dominated
                    else ""
                ),
                "status": "estimated" if name in free else reasons.get(name, "held"),
                "unseen_by_data": fitted.reduction.dropped.get(name, ""),
                "source": source,
            }
        )
    return pd.DataFrame(rows)


def prior_shares(covariance, prior_std) -> np.ndarray:
    """The share of each parameter's posterior variance that the priors set, (P,) in [0, 1]: with
    posterior covariance S = (H + Q)^-1 (H the data's information, Q = diag(1 / prior_std^2) the
    priors'), diag(S Q S) / diag(S), the elasticity of the variance to the priors' scale over 2
    (d S / d s = 2 S Q S at s = 1 for priors scaled by s). 0: the data alone set it; 1: the priors
    do, its own or those of the parameters it trades against (a zero-offset traded against link
    geometry the data cannot tell apart from it). covariance (P, P) SI, prior_std (P,) SI (inf: none)."""
    covariance = np.atleast_2d(np.asarray(covariance, dtype=float))
    precision = np.where(np.isfinite(prior_std), 1.0 / np.square(np.asarray(prior_std, dtype=float)), 0.0)
    variance = np.diag(covariance)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.einsum("ij,j,ji->i", covariance, precision, covariance) / variance
    return np.clip(share, 0.0, 1.0)


def determined_combination(name: str, names, covariance, scale: dict) -> str:
    """What the data determine of parameter `name` when its own posterior is its prior's: the
    parameter less its best linear prediction from the others (the posterior's regression, from the
    precision matrix: its std is the conditional one, 1 / sqrt(precision[i, i])), in `name`'s display
    unit ("+1*name -0.93*other ... (std s)"); "" when `name` is correlated with nothing. names (P,),
    covariance (P, P) SI of the free parameters, scale {name: display unit in SI}."""
    names = list(names)
    if name not in names or len(names) < 2:
        return ""
    i = names.index(name)
    precision = np.linalg.pinv(np.asarray(covariance, dtype=float))
    if not precision[i, i] > 0:
        return ""
    # name - sum_j b_j theta_j with b_j = -precision[i, j] / precision[i, i] (the row of the
    # precision matrix, scaled); in display units the weight of theta_j / scale_j is -b_j scale_j / scale_i
    weights = {
        n: float(precision[i, j] / precision[i, i] * scale[n] / scale[name]) for j, n in enumerate(names) if j != i
    }
    largest = max(abs(w) for w in weights.values())
    kept = sorted(
        ((n, w) for n, w in weights.items() if abs(w) >= COMBINATION_PART * max(largest, 1.0)),
        key=lambda item: -abs(item[1]),
    )[:COMBINATION_TERMS]
    if not kept:
        return ""
    std = 1.0 / np.sqrt(precision[i, i]) / scale[name]
    terms = " ".join(f"{w:+.3g}*{n}" for n, w in kept)
    return f"+1*{name} {terms} (std {std:.3g})"


def zero_offset_shifts(before: pd.DataFrame, after: pd.DataFrame) -> list[dict]:
    """How far each zero-offset moved (deg) and in units of its std before and after."""
    before, after = before.set_index("parameter"), after.set_index("parameter")
    out = []
    for name in [n for n in after.index if n.startswith("zero_offsets.")]:
        first, last = float(before.loc[name, "mean"]) / DEG, float(after.loc[name, "mean"]) / DEG
        row = {
            "parameter": name,
            "before_deg": first,
            "after_deg": last,
            "shift_deg": last - first,
            "std_before_deg": None,
            "std_after_deg": None,
            "shift_in_std_before": None,
            "shift_in_std_after": None,
        }
        if after.loc[name, "status"] == "estimated":
            row["std_before_deg"] = float(before.loc[name, "std"]) / DEG
            row["std_after_deg"] = float(after.loc[name, "std"]) / DEG
            row["shift_in_std_before"] = (last - first) / row["std_before_deg"]
            row["shift_in_std_after"] = (last - first) / row["std_after_deg"]
        out.append(row)
    return out
