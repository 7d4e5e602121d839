"""Convergence and agreement diagnostics for posterior samples: R-hat, bulk and tail ESS, MCSE,
cross-checks between methods.

Sample layouts accepted everywhere: (n, P) one chain in time order; (n, W, P) an ensemble of W
walkers (emcee); or any object with `per_walker()` returning (n, W, P), such as `inference.sampling.target.Chain`.

The estimators are arviz-stats' (Vehtari, Gelman, Simpson, Carpenter and Buerkner 2021, "Rank-
normalization, folding, and localization: an improved R-hat"): the rank-normalised split R-hat
(the larger of the bulk and the folded one), the bulk ESS (rank-normalised), the tail ESS (the
smaller of the 5 % and 95 % quantiles' ESS) and the Monte Carlo standard error of the mean. Every
walker is a chain for the ESS and the MCSE. R-hat compares the chains as given: an ensemble is one
chain, its walkers pooled step by step in time order (the walkers of an affine-invariant ensemble
move by each other's positions, so they are not the independent chains R-hat compares; the fit
passes the two halves of one ensemble as two chains). The ESS's Geyer sequences are computed as
array operations (`_geyer_ess`), to the same float as arviz-stats' own step-by-step loop.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

from .errors import RemasterError

TAU_RELIABLE = 50  # tau is trusted when a walker is at least this many tau long (emcee's default)
TAIL = (0.05, 0.95)  # the quantiles whose ESS is the tail ESS (Vehtari et al. 2021)


class SamplerDisagreement(RemasterError, RuntimeError):
    """Two methods give posterior means further apart than their Monte Carlo errors allow.

    offenders: [(parameter, method, reference, z)] for every disagreement.
    """

    def __init__(self, message: str, offenders: list[tuple[str, str, str, float]]):
        self.offenders = offenders
        super().__init__(message)


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


def _geyer_ess(finish, ary: np.ndarray, autocov: np.ndarray) -> float | None:
    """The effective sample size of chains ary (C, n) with autocovariances autocov (C, n), by
    Geyer's initial positive then monotone sequence, as arviz-stats' `_ess` computes it (every
    operation the same, so the same float), with its step-by-step loops replaced by array
    operations: a chain of a few thousand autocorrelation times ran them for seconds per parameter.
    None where a correlation is not finite: the library's own loop treats those.

    finish(tau_hat, ess) ends as the library does (the floor on tau_hat, relative or not)."""
    n_chain, n_draw = ary.shape
    # the mean over chains at every lag, summed as np.mean sums one lag's column
    acov_mean = np.ascontiguousarray(autocov.T).mean(axis=1)
    mean_var = acov_mean[0] * n_draw / (n_draw - 1.0)
    var_plus = mean_var * (n_draw - 1.0) / n_draw
    if n_chain > 1:
        var_plus += np.var(ary.mean(axis=1), axis=None, ddof=1)
    rho = 1.0 - (mean_var - acov_mean) / var_plus  # the correlation at every lag
    if not np.isfinite(rho).all():
        return None
    rho[0] = 1.0
    pair_sums = rho[0 : n_draw - 1 : 2] + rho[1:n_draw:2]  # lags (0, 1), (2, 3), ...
    # the pairs the initial positive sequence reads: while the previous pair's sum is positive
    last_pair = max((n_draw - 3) // 2, 0)
    nonpositive = np.flatnonzero(pair_sums <= 0.0)
    read = min(last_pair, nonpositive[0] if len(nonpositive) else last_pair)
    kept = np.zeros(n_draw)
    kept[:2] = rho[:2]
    kept_pairs = read if read == 0 or pair_sums[read] >= 0 else read - 1
    kept[2 : 2 * kept_pairs + 2] = rho[2 : 2 * kept_pairs + 2]
    if read and rho[2 * read] > 0:
        kept[2 * read] = rho[2 * read]
    if read >= 2:  # the monotone sequence: a pair's sum is at most the previous pair's
        sums = np.minimum.accumulate(pair_sums[:read])
        raised = np.flatnonzero(pair_sums[1:read] > sums[:-1]) + 1
        kept[2 * raised] = kept[2 * raised + 1] = sums[raised - 1] / 2.0
    max_t = 2 * read - 1
    tau_hat = -1.0 + 2.0 * np.sum(kept[: max_t + 1]) + np.sum(kept[max_t + 1 : max_t + 2])
    return finish(tau_hat, n_chain * n_draw)


def _array_stats():
    """arviz-stats' array statistics with its ESS's Geyer sequence computed by `_geyer_ess`."""
    global _ARRAY_STATS
    if _ARRAY_STATS is None:
        from arviz_stats.base.array import BaseArray  # imports scipy.stats: not in jobs that only read results

        class ArrayStatistics(BaseArray):
            def _ess(self, ary, relative=False):
                ary = np.asarray(ary, dtype=float)
                if (np.max(ary) - np.min(ary)) < np.finfo(float).resolution:
                    return ary.size

                def finish(tau_hat, ess):
                    tau_hat = max(tau_hat, 1 / np.log10(ess))
                    return (1 if relative else ess) / tau_hat

                fast = _geyer_ess(finish, ary, self.autocov(ary, axis=1))
                return super()._ess(ary, relative) if fast is None else fast

        _ARRAY_STATS = ArrayStatistics()
    return _ARRAY_STATS


_ARRAY_STATS = None


def _per_parameter(function, chains: np.ndarray, **options) -> np.ndarray:
    """(P,) an arviz-stats array statistic of chains (C, n, P), NaN where it cannot be computed
    (too few draws, a NaN sample) rather than a warning."""
    import warnings

    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        statistic = getattr(_array_stats(), function)
        return np.asarray(statistic(chains, chain_axis=0, draw_axis=1, **options), dtype=float).reshape(-1)


def rhat(chains: Sequence) -> np.ndarray:
    """(P,) rank-normalised split R-hat (the larger of bulk and folded) across chains.

    chains: list of (n, P) (or (n, W, P) / `Chain`, flattened in time order: an ensemble counts
    as one chain); all are cut to the shortest. Each is split into its first and last halves, so a
    single drifting chain is caught too; one chain alone is given as its two halves (arviz-stats
    compares two chains at least), so its four quarters are compared. About 1 for converged
    chains; above 1.01 - 1.05 means run longer. NaN for a parameter that never moves, a NaN
    sample, or chains under 4 samples.
    """
    flat = [c.reshape(-1, c.shape[-1]) for c in map(_walkers, chains)]
    if len(flat) == 1:
        half = len(flat[0]) // 2
        flat = [flat[0][:half], flat[0][len(flat[0]) - half :]]
    n = min(len(c) for c in flat)
    return _per_parameter("rhat", np.stack([c[:n] for c in flat]), method="rank")


def walker_chains(chains: Sequence) -> np.ndarray:
    """(C, n, P): every walker of every chain as one chain, all cut to the shortest length."""
    walkers = [_walkers(c) for c in chains]
    n = min(len(w) for w in walkers)
    return np.concatenate([np.moveaxis(w[:n], 1, 0) for w in walkers])


def effective_sample_size(samples, method: str = "bulk") -> np.ndarray:
    """(P,) the bulk ("bulk") or tail ("tail") effective sample size of one chain (n, P) or an
    ensemble (n, W, P), every walker a chain; NaN where it cannot be computed."""
    options = {"prob": TAIL} if method == "tail" else {}
    return _per_parameter("ess", walker_chains([samples]), method=method, **options)


def chain_report(chains: Sequence, names: Sequence[str] | None = None) -> pd.DataFrame:
    """Per parameter, over all chains pooled: mean, std, q2.5, q97.5 (SI); mcse (of the mean, SI);
    ess_bulk, ess_tail (every walker a chain); rhat (across the chains as given, `rhat`); tau =
    draws / ess_bulk (steps per effective sample, per walker) and tau_reliable (the walkers at
    least 50 tau long).

    Never raises on what a failed run leaves: a parameter that never moves has rhat NaN (no
    spread to compare), ess one per walker and mcse 0; NaN samples give NaN statistics; chains
    too short for a split R-hat (under 4 states) have rhat NaN, empty ones NaN everywhere and
    ess 0. A NaN rhat or ess is not convergence (`inference.posterior_sampling.converged`)."""
    if names is None:
        names = getattr(chains[0], "names", None)
    walkers = walker_chains(chains)  # (C, n, P)
    n_chains, n, p = walkers.shape
    pooled = walkers.reshape(-1, p)
    names = list(names) if names is not None else [f"theta[{i}]" for i in range(p)]
    with np.errstate(invalid="ignore", divide="ignore"):
        if len(pooled) >= 2:
            std = pooled.std(axis=0, ddof=1)
            q_low, q_high = np.quantile(pooled, [0.025, 0.975], axis=0)
        else:
            std = q_low = q_high = np.full(p, np.nan)
        stuck = std == 0  # no spread: arviz would count every draw as independent
        if n:
            ess_bulk = np.where(stuck, n_chains, _per_parameter("ess", walkers, method="bulk"))
            ess_tail = np.where(stuck, n_chains, _per_parameter("ess", walkers, method="tail", prob=TAIL))
            mcse = np.where(stuck, 0.0, _per_parameter("mcse", walkers, method="mean"))
        else:
            ess_bulk = ess_tail = np.zeros(p)
            mcse = np.full(p, np.nan)
        tau = n * n_chains / ess_bulk
        shortest = min(len(_walkers(c)) * _walkers(c).shape[1] for c in chains)
        table = pd.DataFrame(
            {
                "mean": pooled.mean(axis=0) if len(pooled) else np.full(p, np.nan),
                "std": std,
                "q2.5": q_low,
                "q97.5": q_high,
                "mcse": mcse,
                "ess_bulk": ess_bulk,
                "ess_tail": ess_tail,
                "rhat": rhat(chains) if shortest >= 4 else np.full(p, np.nan),
                "tau": tau,
                "tau_reliable": (TAU_RELIABLE * tau <= n) & ~stuck,
            },
            index=pd.Index(names, name="parameter"),
        )
    return table


def moments(chains: Sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, std, mcse), each (P,), of pooled chains: the input `cross_check` takes per method."""
    report = chain_report(chains)
    return report["mean"].to_numpy(), report["std"].to_numpy(), report["mcse"].to_numpy()


def cross_check(
    results: Mapping[str, tuple],
    names: Sequence[str],
    tolerance: float | None = 4.0,
    reference: str | None = None,
    *,
    floor: float,
) -> pd.DataFrame:
    """Compare posterior means of several methods parameter by parameter.

    results: {method: (mean (P,), std (P,), mcse (P,))}, e.g. `moments(chains)` or
    `LaplaceResult.moments()`; reference: the method the others are compared to (default the
    first). For each other method and parameter

        z = (mean - mean_ref) / max(sqrt(mcse^2 + mcse_ref^2), floor * max(std, std_ref)).

    `floor` (the configuration's fit/cross_check floor, 0.1 by default: one floor for every
    cross-check) is there because least squares has no Monte Carlo error (mcse 0) and a very long
    chain has almost none: without it, differences far below the posterior width that no one cares
    about (the Laplace approximation's own bias, O(1/k)) would count as disagreements. So a method
    agrees if it is within `tolerance` Monte Carlo errors, or within tolerance * floor posterior std.

    Returns a DataFrame indexed by parameter with columns (quantity, method) for quantity in
    mean, std, z (z = 0 for the reference); attrs hold reference, tolerance and floor. With a
    tolerance (the default) it also runs `check_agreement`, raising SamplerDisagreement.
    """
    if not results:
        raise ValueError("cross_check needs at least one method")
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
    table.attrs.update(reference=reference, tolerance=tolerance, floor=floor)
    if tolerance is not None:
        check_agreement(table, tolerance)
    return table


def disagreements(table: pd.DataFrame, tolerance: float | None = None) -> list[tuple[str, str, str, float]]:
    """[(parameter, method, reference, z)] for every |z| of a `cross_check` table beyond
    tolerance, or NaN (a mean or an error that could not be computed is no agreement).

    tolerance defaults to the one the table was made with (4 if none).
    """
    tolerance = tolerance if tolerance is not None else (table.attrs.get("tolerance") or 4.0)
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


def check_agreement(table: pd.DataFrame, tolerance: float | None = None) -> None:
    """Raise SamplerDisagreement if any |z| of a `cross_check` table exceeds tolerance (or is NaN)
    (`disagreements`). tolerance defaults to the one the table was made with (4 if none)."""
    tolerance = tolerance if tolerance is not None else (table.attrs.get("tolerance") or 4.0)
    offenders = disagreements(table, tolerance)
    if offenders:
        z = table["z"]
        lines = [
            f"  {name}: {method} mean {table.loc[name, ('mean', method)]:.6g} vs {ref} "
            f"{table.loc[name, ('mean', ref)]:.6g} (z = {value:+.2f})"
            if ref in z.columns
            else f"  {name}: {method} (z = {value:+.2f})"
            for name, method, ref, value in offenders
        ]
        raise SamplerDisagreement(
            f"posterior means disagree beyond {tolerance:g} combined Monte Carlo errors for "
            f"{len(offenders)} parameter/method pair(s):\n" + "\n".join(lines),
            offenders,
        )
