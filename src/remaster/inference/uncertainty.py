"""Expanded uncertainties (GUM): coverage factors from Student's t at stated degrees of freedom, the
Welch-Satterthwaite effective degrees of freedom, the cluster-robust (CR2, Bell-McCaffrey)
uncertainty of a mean, and the delete-a-group jackknife with the between-design component it gives.

- Coverage factor: k = t_{(1+p)/2}(nu) for coverage probability p (0.95) at nu degrees of freedom;
  nu = inf gives the normal quantile (1.96).
- Welch-Satterthwaite (GUM G.4.1): nu_eff = u_c^4 / sum_i (u_i^4 / nu_i), u_c^2 = sum_i u_i^2;
  components with nu_i = inf (stated or Type B values taken as exact) add nothing to the sum.
- CR2 of a mean (Bell & McCaffrey 2002) of N values e_i grouped in G clusters g of n_g values: the
  residuals r_i = e_i - mean; for an intercept-only model the CR2 variance is
  (1/N^2) sum_g (sum_{i in g} r_i)^2 / (1 - n_g/N), with G - 1 degrees of freedom. With equal
  clusters it is the variance of the cluster means over G, s^2(cluster means) / G.
- Delete-a-group jackknife (Tukey; Kott 2001) of an estimate over K groups: theta_(k) the estimate
  without group k, var = (K-1)/K sum_k (theta_(k) - mean_k theta_(k))^2, K - 1 degrees of freedom.
  For a simple mean over equal groups it is the classical s^2(group means) / K, and with groups of
  one value s^2 / n.
- Between-design component: the jackknife's variance u_J^2 holds the noise's share too, which the
  posterior's u_p^2 already carries; the component beyond it is u_b^2 = max(u_J^2 - u_p^2, 0), so
  that u_c^2 = u_p^2 + u_b^2 = max(u_p^2, u_J^2). u_p is taken as known (nu = inf) and the variance
  u_J^2 as estimated with K - 1 degrees of freedom, which gives nu_eff = (K-1) u_c^4 / u_J^4
  (Welch-Satterthwaite with u_b^2's variance that of u_J^2): K - 1 where the jackknife sets u_c.
"""

from __future__ import annotations

import math

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

COVERAGE = 0.95  # coverage probability of every expanded uncertainty U = k u


def coverage_factor(dof: float, coverage: float = COVERAGE) -> float:
    """k = t_{(1+p)/2}(dof): two-sided coverage p at dof degrees of freedom (inf: the normal
    quantile); NaN for dof NaN or below 1 (no uncertainty to expand)."""
    from scipy import stats

    if dof is None or math.isnan(dof) or dof < 1:
        return math.nan
    quantile = 0.5 * (1.0 + coverage)
    return float(stats.norm.ppf(quantile) if math.isinf(dof) else stats.t.ppf(quantile, dof))


def welch_satterthwaite(u, dof) -> float:
    """Effective degrees of freedom of u_c^2 = sum u_i^2 from components u (m,) with dof (m,)
    (inf where a component is taken as exact); inf when every dof is inf; NaN when u_c = 0."""
    u, dof = np.asarray(u, dtype=float), np.asarray(dof, dtype=float)
    total = float(np.sum(u**2))
    if total == 0.0:
        return math.nan
    finite = np.isfinite(dof)
    denominator = float(np.sum(u[finite] ** 4 / dof[finite]))
    return math.inf if denominator == 0.0 else total**2 / denominator


def cr2_mean(values, clusters) -> tuple[float, float, int]:
    """(mean, CR2 standard uncertainty of the mean, number of clusters G) of values (N,) grouped by
    clusters (N,) (module docstring); NaNs dropped; u NaN with fewer than two clusters. Its degrees
    of freedom are G - 1."""
    values, clusters = np.asarray(values, dtype=float), np.asarray(clusters)
    seen = np.isfinite(values)
    values, clusters = values[seen], clusters[seen]
    n = len(values)
    if n == 0:
        return math.nan, math.nan, 0
    mean = float(values.mean())
    labels, index = np.unique(clusters, return_inverse=True)
    if len(labels) < 2:
        return mean, math.nan, len(labels)
    sums = np.bincount(index, weights=values - mean)
    sizes = np.bincount(index)
    variance = float(np.sum(sums**2 / (1.0 - sizes / n))) / n**2
    return mean, math.sqrt(variance), len(labels)


def jackknife_variance(estimates) -> np.ndarray:
    """Delete-a-group jackknife variance (P,) from the K leave-one-group-out estimates (K, P) (or
    (K,)): (K-1)/K sum_k (theta_(k) - mean)^2; its degrees of freedom are K - 1."""
    estimates = np.asarray(estimates, dtype=float)
    k = estimates.shape[0]
    return (k - 1) / k * np.sum((estimates - estimates.mean(axis=0)) ** 2, axis=0)


def between_design(u_posterior, u_jackknife, groups: int) -> tuple[np.ndarray, np.ndarray]:
    """(u_between, nu_eff) per parameter from the posterior std u_posterior (P,) and the jackknife
    std u_jackknife (P,) over `groups` groups (module docstring): u_between = sqrt(max(u_J^2 -
    u_p^2, 0)) and the degrees of freedom of the combined u (`with_between`)."""
    u_p, u_j = np.asarray(u_posterior, dtype=float), np.asarray(u_jackknife, dtype=float)
    u_b = np.sqrt(np.maximum(u_j**2 - u_p**2, 0.0))
    return u_b, with_between(u_p, u_b, u_j, groups)[1]


def with_between(u_posterior, u_between, u_jackknife, groups: int, u_model=0.0) -> tuple[np.ndarray, np.ndarray]:
    """(u_c, nu_eff) of u_c^2 = u_p^2 + u_b^2 + u_m^2, u_p and the model error's share u_m (a Type B
    component, `remaster.loop.model_error_share`; 0 where there is none) taken as known and u_b^2 as a
    difference whose variance is that of the jackknife's u_J^2 over K = `groups` groups:
    nu_eff = (K-1) u_c^4 / u_J^4 (Welch-Satterthwaite), inf where u_J = 0. Arrays (P,) or scalars."""
    u_p, u_b, u_j, u_m = (np.asarray(v, dtype=float) for v in (u_posterior, u_between, u_jackknife, u_model))
    combined = u_p**2 + u_b**2 + u_m**2
    with np.errstate(divide="ignore", invalid="ignore"):
        dof = np.where(u_j > 0, (groups - 1) * combined**2 / np.where(u_j > 0, u_j, 1.0) ** 4, np.inf)
    return np.sqrt(combined), dof
