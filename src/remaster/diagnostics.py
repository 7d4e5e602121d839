"""Convergence and agreement diagnostics for posterior samples: rank-normalised split R-hat, bulk
and tail effective sample sizes, Monte Carlo standard error of the mean, and the agreement of
several methods' posterior means.

The estimators are those of Vehtari, Gelman, Simpson, Carpenter and Buerkner (2021), "Rank-
normalization, folding, and localization: an improved R-hat for assessing convergence of MCMC",
Bayesian Analysis 16(2), as `arviz_stats` computes them on (chain, draw) arrays. arviz_stats (and
with it scipy.stats and scipy.optimize) is imported in the functions that compute, so that a job
that only reads results does not load it (test_architecture).

Sample layouts accepted everywhere: (n, P) one chain in time order; (n, W, P) an ensemble of W
walkers (emcee); or any object with `per_walker()` returning (n, W, P), such as `samplers.Chain`.
Every walker counts as one chain, as ArviZ counts emcee's. The walkers of an ensemble are not
independent chains: at stationarity the W walkers at one step are independent draws (the stretch
move leaves the product of W targets invariant), but each walker's moves are drawn from the
others' positions, so their paths are coupled. emcee therefore estimates one integrated
autocorrelation time from the walkers' averaged autocorrelation functions; the ESS here averages
the walkers' autocovariances in the same way, and both ignore the cross-correlation of two
walkers' paths at non-zero lag. R-hat over walkers asks the stricter question whether every walker
has explored the same distribution. No autocorrelation time is kept: nothing in remaster thins or
stops on one (the samplers run on while R-hat or ESS misses the criteria, `inference.fit`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np  # arviz_stats is imported in the functions that use it (test_architecture: light readers)
import pandas as pd

TAIL_PROBABILITIES = (0.05, 0.95)  # tail ESS: the smaller ESS of the 5 % and 95 % quantiles (Vehtari et al.)


def _walkers(samples) -> np.ndarray:
    """Any accepted layout -> (n, W, P) float array."""
    if hasattr(samples, "per_walker"):
        return np.asarray(samples.per_walker(), dtype=float)
    x = np.asarray(samples, dtype=float)
    if x.ndim == 2:
        return x[:, None, :]
    if x.ndim != 3:
        raise ValueError(f"samples must be (n, P) or (n, W, P), got shape {x.shape}")
    return x


STATISTICS = ("rhat", "ess_bulk", "ess_tail", "mcse_mean")


def _parameters(chains: Sequence):
    """Each parameter's draws as a (C, n) array, arviz's (chain, draw) layout: every walker of
    every chain one of the C chains, in order, all cut to the shortest length n (every sampler
    here gives equal lengths; the statistics need a rectangular array). One parameter at a time:
    an ensemble run long holds gigabytes of draws, and a copy of all of them is not needed."""
    walkers = [_walkers(c) for c in chains]
    n = min(len(w) for w in walkers)
    for d in range(walkers[0].shape[2]):
        yield np.concatenate([w[:n, :, d] for w in walkers], axis=1).T


def _statistic(draws: np.ndarray, statistic: str) -> float:
    """One of STATISTICS of one parameter's draws (C, n) (`convergence`)."""
    from arviz_stats.base import array_stats  # scipy.stats and scipy.optimize: not for light readers

    if draws.shape[1] == 0 or (statistic != "rhat" and not np.ptp(draws) > 0):  # empty, NaN or never moved
        return np.nan
    with np.errstate(invalid="ignore", divide="ignore"):  # 0 / 0 where a chain never moved: NaN
        if statistic == "rhat":
            return float(array_stats.rhat(draws, method="rank"))
        if statistic == "ess_bulk":
            return float(array_stats.ess(draws, method="bulk"))
        if statistic == "ess_tail":
            return float(array_stats.ess(draws, method="tail", prob=TAIL_PROBABILITIES))
        if statistic == "mcse_mean":
            return float(array_stats.mcse(draws, method="mean"))
    raise ValueError(f"unknown statistic {statistic!r}; use one of {STATISTICS}")


def convergence(chains: Sequence, statistics: Sequence[str] = STATISTICS) -> dict[str, np.ndarray]:
    """{statistic: (P,)} for each of `statistics` of chains pooled (a list of any accepted layout,
    every walker a chain: see the module's docstring):

    rhat: rank-normalised split R-hat, the larger of the bulk's (rank-normalised draws) and the
    tails' (the same of the draws folded about their median), every chain split in halves so
    that one still drifting is caught. About 1 for converged chains; Vehtari et al. ask for
    < 1.01, remaster's criterion is fit/cross_check/max_rhat.
    ess_bulk: effective sample size of the rank-normalised draws, what the centre of the
    posterior (mean, median) is worth; ess_tail: the smaller ESS of the 5 % and 95 % quantiles
    (TAIL_PROBABILITIES), what the intervals are worth.
    mcse_mean: Monte Carlo standard error of the posterior mean, std / sqrt(ESS of the mean) (the
    split chains' ESS without rank normalisation), in the parameter's units (SI).

    Never raises on what a failed run leaves: R-hat needs at least 2 chains, every statistic 4
    draws per chain, else NaN; a NaN draw makes its parameter's statistics NaN; a parameter that
    never moves (every draw equal) has rhat NaN (no spread to compare) and its ESS and MCSE NaN
    too (arviz would count its draws as independent, and they would pass any ESS criterion). A
    NaN rhat or ESS is not convergence (`inference.fit.converged`)."""
    values = [[_statistic(draws, s) for s in statistics] for draws in _parameters(chains)]
    table = np.array(values, dtype=float).reshape(-1, len(statistics))
    return {s: table[:, k] for k, s in enumerate(statistics)}


def chain_report(chains: Sequence, names: Sequence[str] | None = None) -> pd.DataFrame:
    """Per parameter, over all chains pooled: mean, std, q2.5, q97.5 (SI), and `convergence`'s
    rhat, ess_bulk, ess_tail and mcse_mean. Never raises on what a failed run leaves: NaN where a
    statistic is undefined (`convergence`), empty chains NaN everywhere."""
    if names is None:
        names = getattr(chains[0], "names", None)
    walkers = [_walkers(c) for c in chains]
    pooled = np.concatenate([w.reshape(-1, w.shape[-1]) for w in walkers])
    p = pooled.shape[1]
    names = list(names) if names is not None else [f"theta[{i}]" for i in range(p)]
    with np.errstate(invalid="ignore", divide="ignore"):
        if len(pooled) >= 2:
            std = pooled.std(axis=0, ddof=1)
            q_low, q_high = np.quantile(pooled, [0.025, 0.975], axis=0)
        else:
            std = q_low = q_high = np.full(p, np.nan)
        table = pd.DataFrame(
            {
                "mean": pooled.mean(axis=0) if len(pooled) else np.full(p, np.nan),
                "std": std,
                "q2.5": q_low,
                "q97.5": q_high,
                **convergence(walkers),
            },
            index=pd.Index(names, name="parameter"),
        )
    return table


def moments(chains: Sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, std, mcse_mean), each (P,), of pooled chains: the input `agreement` takes per method."""
    report = chain_report(chains)
    return report["mean"].to_numpy(), report["std"].to_numpy(), report["mcse_mean"].to_numpy()


def agreement(
    results: Mapping[str, tuple], names: Sequence[str], floor: float, reference: str | None = None
) -> pd.DataFrame:
    """Posterior means of several methods compared parameter by parameter: the arithmetic of the
    cross-check (`inference.fit.cross_check`, which passes the configuration's floor).

    results: {method: (mean (P,), std (P,), mcse (P,))}, e.g. `moments(chains)` or
    `LaplaceResult.moments()`; reference: the method the others are compared to (default the
    first). For each other method and parameter

        z = (mean - mean_ref) / max(sqrt(mcse^2 + mcse_ref^2), floor * max(std, std_ref)).

    The floor (a fraction of the larger posterior std) is there because least squares has no
    Monte Carlo error (mcse 0) and a very long chain has almost none: without it, differences far
    below the posterior width that no one cares about (the Laplace approximation's own bias,
    O(1/k)) would count as disagreements.

    Returns a DataFrame indexed by parameter with columns (quantity, method) for quantity in
    mean, std, z (z = 0 for the reference); attrs hold reference and floor. `disagreements`
    reads it.
    """
    if not results:
        raise ValueError("agreement needs at least one method")
    names = list(names)
    reference = reference if reference is not None else next(iter(results))
    if reference not in results:
        raise ValueError(f"reference method {reference!r} is not among {list(results)}")
    parsed = {}
    for method, values in results.items():
        mean, std, mcse = (np.asarray(v, dtype=float) for v in values)
        for label, array in (("mean", mean), ("std", std), ("mcse", mcse)):
            if array.shape != (len(names),):
                raise ValueError(f"{method} {label} has shape {array.shape}, expected ({len(names)},)")
        parsed[method] = (mean, std, mcse)
    ref_mean, ref_std, ref_mcse = parsed[reference]
    columns = {}
    for method, (mean, std, mcse) in parsed.items():
        error = np.maximum(np.hypot(mcse, ref_mcse), floor * np.maximum(std, ref_std))
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.zeros(len(names)) if method == reference else (mean - ref_mean) / error
        columns[("mean", method)], columns[("std", method)], columns[("z", method)] = mean, std, z
    table = pd.DataFrame(columns, index=pd.Index(names, name="parameter"))
    table.columns = pd.MultiIndex.from_tuples(table.columns, names=["quantity", "method"])
    table = table.sort_index(axis=1, level=0, sort_remaining=False)
    table.attrs.update(reference=reference, floor=floor)
    return table


def disagreements(table: pd.DataFrame, tolerance: float) -> list[tuple[str, str, str, float]]:
    """[(parameter, method, reference, z)] for every |z| of an `agreement` table beyond
    tolerance, or NaN (a mean or an error that could not be computed is no agreement)."""
    z = table["z"]
    reference = table.attrs.get("reference")
    if reference not in z.columns:  # attrs lost on the way: the reference is the all-zero z column
        reference = next((m for m in z.columns if (z[m] == 0).all()), None)
    offenders = []
    for method in z.columns:
        if method == reference:
            continue
        for name, value in z[method].items():
            if not abs(value) <= tolerance:  # NaN counts as a disagreement
                offenders.append((str(name), str(method), str(reference), float(value)))
    return offenders
