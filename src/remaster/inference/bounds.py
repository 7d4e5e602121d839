"""The 95 % bound on a position error: the one quantile behind every "95 % bound" the library states.

Two questions, answered from posterior draws or from a covariance:

- **Where may the point at this configuration be?** `bound_at_points`: at each configuration, the
  95th percentile over the posterior draws of the distance between a draw's point and the
  prediction (`remaster predict` and `compensate`: bound95_mm). `bound_from_covariances` answers the
  same question from the covariance of the linearized posterior, without draws (the planner: its
  thousands of candidates x evaluation points could not afford draws).
- **What 95th-percentile error will one arm have over these configurations?**
  `bound_on_percentile_over_configurations`: one arm is one draw of the posterior; its own 95th
  percentile of the error over the configurations, bounded with 95 % posterior probability (the 95th
  percentile over draws of each draw's 95th percentile over configurations: the workspace claims'
  p95_bound_mm). An arm whose parameters lie out in the posterior's tail errs more everywhere at
  once, so this exceeds the 95th percentile of the pooled errors.

SI in and out (m, m^2, m^4).
"""

from __future__ import annotations

import numpy as np

QUANTILE = 0.95


def bound_at_points(distances) -> np.ndarray:
    """95 % bound (n,) m at each of n configurations from distances (K, n) m of K posterior draws to
    the prediction: their 95th percentile over the draws. NaN without draws (K = 0)."""
    distances = np.asarray(distances, dtype=float)
    if len(distances) == 0:
        return np.full(distances.shape[1:], np.nan)
    return np.quantile(distances, QUANTILE, axis=0)


def bound_on_percentile_over_configurations(distances) -> float:
    """95 % bound (m) on one arm's 95th-percentile error over the configurations, from distances
    (K, n) m of K posterior draws at n configurations (module docstring). NaN without distances."""
    distances = np.asarray(distances, dtype=float)
    if distances.size == 0:
        return np.nan
    return float(np.quantile(np.quantile(distances, QUANTILE, axis=-1), QUANTILE))


def bound_from_moments(trace, frobenius2) -> np.ndarray:
    """95 % bound of |x| (m) for x ~ N(0, C) from tr C and |C|_F^2 (any shape, m^2 and m^4).

    |x|^2 is a sum of l_i chi2_1 (l_i the eigenvalues of C); it is taken as c chi2_nu with
    c = sum l_i^2 / sum l_i, nu = (sum l_i)^2 / sum l_i^2 (the Welch-Satterthwaite match of the
    first two moments): exact for an isotropic C (nu = 3) and for a rank-one one (nu = 1), within a
    few percent between, and it needs only the trace and the Frobenius norm of C. It is not the
    closure test's three-moment match (`chi_square.pearson_sf`), which would need tr C^3 as well for
    every candidate x evaluation point of the planner and gives other numbers between those cases."""
    from scipy.special import chdtri

    trace = np.maximum(np.asarray(trace, dtype=float), 0.0)
    frobenius2 = np.maximum(np.asarray(frobenius2, dtype=float), 1e-300)
    c = frobenius2 / np.maximum(trace, 1e-300)
    nu = np.clip(trace**2 / frobenius2, 1.0, 3.0)
    return np.sqrt(c * chdtri(nu, 1.0 - QUANTILE))


def bound_from_covariances(covariances) -> np.ndarray:
    """95 % bounds (E,) m of positions with covariances (E, 3, 3) m^2 about their prediction: what
    `bound_at_points` gives from draws of a Gaussian posterior (`bound_from_moments`)."""
    c = np.asarray(covariances, dtype=float)
    return bound_from_moments(np.trace(c, axis1=-2, axis2=-1), np.sum(c * c, axis=(-2, -1)))
