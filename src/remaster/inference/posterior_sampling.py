"""The samplers run on a model's posterior (`sample`: the paper's Metropolis, the adaptive one from
overdispersed starts, emcee), each on until its convergence criteria hold; their chains as tables
(`samples_frame`, `trace_frame`, `chains_of`) and their diagnostics (`sampler_diagnostics`,
`converged`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

from .. import diagnostics
from ..files import number_or_nan
from .blocks import BlockModel
from .laplace_report import LaplaceReport
from .posterior_targets import PosteriorTarget
from .sampling.chains import run_chains, run_emcee
from .sampling.metropolis import metropolis_adaptive, metropolis_paper
from .sampling.target import Chain

# --------------------------------------------------------------------------- fitting

METHODS = ("paper", "default", "emcee")
METHOD_LABELS = {
    "paper": "Metropolis (paper)",
    "default": "adaptive Metropolis",
    "emcee": "emcee",
    "laplace": "least squares + Laplace",
}


def sample(
    model: BlockModel, laplace: LaplaceReport, method: str, settings: dict, rng: np.random.Generator, progress=None
) -> list[Chain]:
    """Chains of one method on the model's posterior.

    paper: the paper's Metropolis from Theta = 0, sigma = 1 mm; default: adaptive Metropolis from
    overdispersed starts drawn from the Laplace approximation (`overdispersed_starts`), proposal
    seeded by the Laplace covariance, run on until the convergence criteria hold
    (settings["convergence"]: max_rhat, min_ess; its kept part doubled at most
    settings["max_doublings"] times); emcee: walkers in a Laplace-sized ball around the MAP (one
    ensemble, its walkers split in two halves for R-hat), doubled the same way.
    """
    target = PosteriorTarget(model)
    start, covariance = laplace.start()
    if method == "paper":
        paper_start = np.append(np.zeros(len(model.names)), 1e-3)
        return run_chains(
            metropolis_paper,
            target,
            rng,
            settings["chains"],
            paper_start,
            n_samples=settings["samples"],
            burn_in=settings["burn_in"],
            half_width=settings["half_width"],
            progress=progress,
        )
    if method == "default":
        return run_chains(
            metropolis_adaptive,
            target,
            rng,
            settings["chains"],
            overdispersed_starts(start, covariance, settings["chains"], rng),
            enough=_converged_chains(target.names, settings.get("convergence")),
            max_doublings=settings.get("max_doublings", 0),
            covariance=covariance,
            n_samples=settings["samples"],
            burn_in=settings["burn_in"],
            progress=progress,
        )
    if method == "emcee":
        return [
            run_emcee(
                target,
                rng,
                start,
                np.sqrt(np.diag(covariance)),
                n_walkers=settings["walkers"],
                n_steps=settings["steps"],
                burn_in=settings["burn_in"],
                enough=converged_ensemble(target.names, settings.get("convergence")),
                max_doublings=settings.get("max_doublings", 0),
            )
        ]
    raise ValueError(f"unknown sampling method {method!r}; use one of {METHODS}")


OVERDISPERSION = 3.0  # the default sampler's chains start this many Laplace std from the MAP


def overdispersed_starts(start, covariance, n_chains: int, rng: np.random.Generator) -> np.ndarray:
    """(n_chains, P) starts start + OVERDISPERSION L z, L L^T = covariance (the Laplace
    approximation's), z ~ N(0, I): three std out along the posterior's own shape. Drawn
    independently per coordinate, three std out in a direction the parameters' correlation makes
    narrow would be hundreds of std from the posterior, a start the adaptive burn-in spends its
    steps coming back from. sigma (last) stays positive."""
    start = np.asarray(start, dtype=float)
    covariance = np.asarray(covariance, dtype=float)
    try:
        factor = np.linalg.cholesky(covariance)
    except np.linalg.LinAlgError:  # not positive definite by round-off: the marginal std alone
        factor = np.diag(np.sqrt(np.clip(np.diag(covariance), 0.0, None)))
    starts = start + OVERDISPERSION * rng.standard_normal((n_chains, len(start))) @ factor.T
    starts[:, -1] = np.abs(starts[:, -1])
    return starts


def _converged_chains(names, criteria: Mapping | None):
    """The test that chains meet the cross-check's criteria (max_rhat, min_ess), judged as
    `sampler_diagnostics` judges them; None without criteria."""
    if criteria is None:
        return None

    def enough(chains) -> bool:
        report = diagnostics.chain_report(chains, list(names))
        return converged(_extremes(report), criteria["max_rhat"], criteria["min_ess"])

    return enough


def _extremes(report: pd.DataFrame) -> dict:
    """{'max_rhat', 'min_ess'} of a `diagnostics.chain_report` (min_ess: the smaller of the bulk
    and the tail ESS), NaN when any parameter's is NaN (a parameter whose chains never move has
    no R-hat: that is not convergence, and a max that skipped it would say it is)."""
    rhat = report["rhat"].to_numpy(dtype=float)
    ess = np.minimum(report["ess_bulk"].to_numpy(dtype=float), report["ess_tail"].to_numpy(dtype=float))
    return {
        "max_rhat": float(np.max(rhat)) if rhat.size else math.nan,
        "min_ess": float(np.min(ess)) if ess.size else math.nan,
    }


def converged_ensemble(names, criteria: Mapping | None):
    """The test that an ensemble's kept paths (n_steps, n_walkers, P) meet the cross-check's
    criteria (max_rhat, min_ess), judged as `sampler_diagnostics` judges it (the walkers' two
    halves as two chains); None without criteria."""
    if criteria is None:
        return None

    def enough(paths: np.ndarray) -> bool:
        half = paths.shape[1] // 2
        report = diagnostics.chain_report([paths[:, :half], paths[:, half:]], list(names))
        return converged(_extremes(report), criteria["max_rhat"], criteria["min_ess"])

    return enough


def samples_frame(chains: list[Chain]) -> pd.DataFrame:
    """Posterior samples (SI), one row per kept state: parameters, log_prob, chain, walker, step."""
    frames = []
    for number, chain in enumerate(chains):
        steps = np.repeat(np.arange(chain.n_steps), chain.n_walkers)
        walkers = np.tile(np.arange(chain.n_walkers), chain.n_steps)
        frame = pd.DataFrame(chain.samples, columns=list(chain.names))
        frame["log_prob"] = chain.log_prob
        frame["chain"] = np.int64(number)
        frame["walker"] = walkers.astype(np.int64)
        frame["step"] = steps.astype(np.int64)
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def trace_frame(chains: list[Chain], every: int = 100) -> pd.DataFrame:
    """The whole run of each chain, every `every`-th step, burn-in included where the sampler
    kept it (the paper's); step counts from the first step. For an ensemble, walker 0."""
    frames = []
    for number, chain in enumerate(chains):
        burn_in = chain.settings.get("burn_in", 0)
        kept = chain.per_walker()[::every, 0]
        parts, steps = [kept], [burn_in + every * np.arange(len(kept))]
        if "burn_in_trace" in chain.settings:
            early = chain.settings["burn_in_trace"]
            parts.insert(0, early)
            steps.insert(0, chain.settings["trace_every"] * np.arange(len(early)))
        frame = pd.DataFrame(np.concatenate(parts), columns=list(chain.names))
        frame["step"] = np.concatenate(steps).astype(np.int64)
        frame["chain"] = np.int64(number)
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def chains_of(frame: pd.DataFrame, names) -> list[np.ndarray]:
    """Samples back into per-chain (n, W, P) arrays, the layout the diagnostics take."""
    out = []
    for _, part in frame.groupby("chain", sort=True):
        walkers = int(part["walker"].max()) + 1
        values = part.sort_values(["step", "walker"])[list(names)].to_numpy()
        out.append(values.reshape(-1, walkers, len(names)))
    if len(out) == 1 and out[0].shape[1] >= 4:  # one ensemble: its two halves of walkers as two chains
        half = out[0].shape[1] // 2
        out = [out[0][:, :half], out[0][:, half:]]
    return out


def sampler_diagnostics(chains: list[Chain], seconds: float) -> dict:
    """JSON-ready: per-parameter report (tau, ESS, R-hat, MCSE), acceptance, ESS per second, and
    how often the run doubled to meet its criteria. min_ess and max_rhat are NaN (null in the
    file) when a parameter's is: `converged` then says no, as it must for a chain that never
    moved."""
    frame = samples_frame(chains)
    names = list(chains[0].names)
    report = diagnostics.chain_report(chains_of(frame, names), names)
    extremes = _extremes(report)
    return {
        "method": chains[0].method,
        "chains": len(chains),
        "walkers": chains[0].n_walkers,
        "kept_per_chain": chains[0].n_steps,
        "doublings": int(chains[0].settings.get("doublings", 0)),
        "acceptance_rate": [c.acceptance_rate for c in chains],
        "seconds": seconds,
        "min_ess": extremes["min_ess"],
        "min_ess_per_second": extremes["min_ess"] / seconds if seconds > 0 else None,
        "max_rhat": extremes["max_rhat"],
        "rhat_undefined": [n for n, r in report["rhat"].items() if not np.isfinite(r)],
        "parameters": report.reset_index().to_dict(orient="records"),
    }


def converged(diagnostics_report: Mapping | None, max_rhat: float, min_ess: float) -> bool:
    """A sampler's own verdict: every R-hat below max_rhat and every ESS above min_ess. A value
    that is missing, None (NaN as a JSON file holds it) or NaN is not a pass: no diagnostics,
    no verdict of convergence."""
    report = diagnostics_report or {}
    rhat, ess = number_or_nan(report.get("max_rhat")), number_or_nan(report.get("min_ess"))
    return rhat <= max_rhat and ess >= min_ess  # False for NaN
