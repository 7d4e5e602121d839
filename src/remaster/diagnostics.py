"""Convergence and agreement diagnostics for posterior samples: tau, ESS, split-R-hat, cross-checks.

Sample layouts accepted everywhere: (n, P) one chain in time order; (n, W, P) an ensemble of W
walkers (emcee); or any object with `per_walker()` returning (n, W, P), such as `samplers.Chain`.

The Monte Carlo standard error of a posterior mean is std / sqrt(ESS), ESS = n W / tau, tau the
integrated autocorrelation time (emcee's estimator, Sokal's automatic window with c = 5).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

from .errors import RemasterError

TAU_RELIABLE = 50  # tau is trusted when the chain is at least this many tau long (emcee's default)
MCSE_FLOOR = 0.05  # cross-check errors are at least this fraction of the posterior std


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


@dataclass(frozen=True)
class Autocorrelation:
    """tau (P,) integrated autocorrelation time in steps; reliable (P,) True where the chain is
    at least TAU_RELIABLE tau long; n steps per walker; n_walkers."""

    tau: np.ndarray
    reliable: np.ndarray
    n: int
    n_walkers: int

    @property
    def ess(self) -> np.ndarray:
        """(P,) effective sample size n W / tau."""
        return self.n * self.n_walkers / self.tau


def autocorrelation(samples, tol: float = TAU_RELIABLE) -> Autocorrelation:
    """Integrated autocorrelation time of each parameter, never raising on short chains.

    For an ensemble the autocorrelation functions of the walkers are averaged (emcee's
    estimator). A chain shorter than tol * tau gets its (underestimated) tau with reliable False;
    a parameter that never moves, or a chain under 4 steps, gets tau = n (ESS = W), unreliable.
    """
    x = _walkers(samples)
    n, w, p = x.shape
    if n < 4:
        return Autocorrelation(np.full(p, float(n)), np.zeros(p, bool), n, w)
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = _integrated_time(x, window_factor=5.0)
    stuck = ~np.isfinite(tau)
    tau[stuck] = n
    return Autocorrelation(tau, (tol * tau <= n) & ~stuck, n, w)


def _integrated_time(x: np.ndarray, window_factor: float) -> np.ndarray:
    """(P,) Sokal's windowed estimate of tau for x (n, W, P): the walkers' normalised
    autocorrelation functions (by FFT, zero-padded past twice the next power of two) averaged,
    tau(M) = 1 + 2 sum_{t=1..M} rho(t), at the smallest window M >= window_factor tau(M) (the
    last lag when none is). The same estimator as emcee.autocorr.integrated_time, written here
    so that a job reading chains does not import emcee (and with it scipy.stats)."""
    n, w, p = x.shape
    size = 1 << max(n - 1, 0).bit_length()  # the next power of two >= n
    tau = np.empty(p)
    for d in range(p):
        rho = np.zeros(n)
        for k in range(w):  # summed walker by walker, in order: the same floating-point sums as emcee
            series = x[:, k, d]
            f = np.fft.fft(series - np.mean(series), n=2 * size)
            acf = np.fft.ifft(f * np.conjugate(f))[:n].real
            rho += acf / acf[0]
        rho /= w
        taus = 2.0 * np.cumsum(rho) - 1.0
        short = np.arange(n) < window_factor * taus
        tau[d] = taus[np.argmin(short) if short.any() else n - 1]
    return tau


def integrated_autocorr_time(samples) -> np.ndarray:
    """(P,) integrated autocorrelation time in steps; see `autocorrelation` for the flag."""
    return autocorrelation(samples).tau


def effective_sample_size(samples) -> np.ndarray:
    """(P,) n W / tau."""
    return autocorrelation(samples).ess


def split_rhat(chains: Sequence) -> np.ndarray:
    """(P,) Gelman-Rubin potential scale reduction over the halves of every chain.

    chains: list of (n, P) (or (n, W, P) / `Chain`, flattened in time order: an ensemble counts
    as one chain). All are cut to the shortest length; each is split into its first and last
    halves, so a single drifting chain is caught too. With h the half length:
    R = sqrt(((h - 1) / h W + B / h) / W), W the mean within-half variance, B / h the variance
    of the half means. About 1 for converged chains; > 1.01 - 1.1 means run longer.
    """
    flat = [_walkers(c) for c in chains]
    flat = [c.reshape(-1, c.shape[-1]) for c in flat]
    n = min(len(c) for c in flat)
    h = n // 2
    if h < 2:
        raise ValueError(f"split-R-hat needs chains of at least 4 samples, the shortest has {n}")
    halves = np.stack([part for c in flat for part in (c[:h], c[len(c) - h :])])  # (2C, h, P)
    within = halves.var(axis=1, ddof=1).mean(axis=0)
    between_over_h = halves.mean(axis=1).var(axis=0, ddof=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(((h - 1) / h * within + between_over_h) / within)


def chain_report(chains: Sequence, names: Sequence[str] | None = None) -> pd.DataFrame:
    """Per parameter, over all chains pooled: mean, std, q2.5, q97.5 (SI), tau (mean over chains,
    steps), ess (sum over chains), rhat (split, across chains), mcse = std / sqrt(ess), and
    tau_reliable (every chain at least 50 tau long).

    Never raises on what a failed run leaves: a parameter that never moves has rhat NaN (no
    spread to compare) and ess = the number of walkers; NaN samples give NaN statistics; chains
    too short for a split R-hat (under 4 states) have rhat NaN, empty ones NaN everywhere and
    ess 0. A NaN rhat or ess is not convergence (`inference.fit.converged`)."""
    if names is None:
        names = getattr(chains[0], "names", None)
    walkers = [_walkers(c) for c in chains]
    pooled = np.concatenate([w.reshape(-1, w.shape[-1]) for w in walkers])
    p = pooled.shape[1]
    names = list(names) if names is not None else [f"theta[{i}]" for i in range(p)]
    autocorr = [autocorrelation(w) for w in walkers]
    with np.errstate(invalid="ignore", divide="ignore"):
        ess = np.sum([np.where(a.n > 0, a.ess, 0.0) for a in autocorr], axis=0)
        if len(pooled) >= 2:
            std = pooled.std(axis=0, ddof=1)
            q_low, q_high = np.quantile(pooled, [0.025, 0.975], axis=0)
        else:
            std = q_low = q_high = np.full(p, np.nan)
        shortest = min(len(w) * w.shape[1] for w in walkers)
        table = pd.DataFrame(
            {
                "mean": pooled.mean(axis=0) if len(pooled) else np.full(p, np.nan),
                "std": std,
                "q2.5": q_low,
                "q97.5": q_high,
                "tau": np.mean([a.tau for a in autocorr], axis=0),
                "ess": ess,
                "rhat": split_rhat(walkers) if shortest >= 4 else np.full(p, np.nan),
                "mcse": std / np.sqrt(ess),
                "tau_reliable": np.all([a.reliable for a in autocorr], axis=0),
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
    floor: float = MCSE_FLOOR,
) -> pd.DataFrame:
    """Compare posterior means of several methods parameter by parameter.

    results: {method: (mean (P,), std (P,), mcse (P,))}, e.g. `moments(chains)` or
    `LaplaceResult.moments()`; reference: the method the others are compared to (default the
    first). For each other method and parameter

        z = (mean - mean_ref) / max(sqrt(mcse^2 + mcse_ref^2), floor * max(std, std_ref)).

    The floor (5 % of the larger posterior std) is there because least squares has no Monte Carlo
    error (mcse 0) and a very long chain has almost none: without it, differences far below the
    posterior width that no one cares about (the Laplace approximation's own bias, O(1/k)) would
    count as disagreements. So a method agrees if it is within `tolerance` Monte Carlo errors, or
    within tolerance * 5 % = 0.2 posterior std at the default tolerance of 4.

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
