"""Weighted sums of chi-square variables: their first three cumulants, and Pearson's approximation of
their law by one shifted, scaled chi-square.

Q = sum_i w_i chi2_1 (independent terms, weights w_i >= 0) has the cumulants
kappa_j = 2^(j-1) (j-1)! sum_i w_i^j: (sum w, 2 sum w^2, 8 sum w^3); chi-square with k degrees of
freedom (every weight 1) has (k, 2k, 8k). Pearson's three-moment approximation takes Q as
a + b chi2_d with the same three cumulants: b = kappa_3 / (4 kappa_2), d = 8 kappa_2^3 / kappa_3^2,
a = kappa_1 - b d; it is exact for chi-square itself. The loop's closure test (`loop.noise_floor`)
takes a correct model's held-out sum of squares (`evidence.held_out_cumulants`) so.

The 95 % bound of a position error (`bounds.bound_from_moments`) matches a weighted sum of three
chi2_1 by its first two moments only, without a shift (Welch-Satterthwaite): it needs no third
cumulant (tr C^3) over the planner's thousands of covariances, and is exact where this one is
exact for three terms (equal weights, or one), but gives other numbers between: it is not this
approximation, and is kept apart.

Dimensionless: Q is a sum of squares over a variance.
"""

from __future__ import annotations

import numpy as np


def cumulants(dof: int) -> tuple[float, float, float]:
    """The first three cumulants (k, 2k, 8k) of chi-square with k = `dof` degrees of freedom."""
    return (float(dof), 2.0 * dof, 8.0 * dof)


def weighted_cumulants(weights) -> tuple[float, float, float]:
    """The first three cumulants (sum w, 2 sum w^2, 8 sum w^3) of sum_i w_i chi2_1, weights (n,)."""
    w = np.asarray(weights, dtype=float)
    return (float(np.sum(w)), 2.0 * float(np.sum(w**2)), 8.0 * float(np.sum(w**3)))


def pearson(cumulants) -> tuple[float, float, float]:
    """(shift a, scale b, degrees of freedom d) of a + b chi2_d with the three cumulants given."""
    k1, k2, k3 = (float(c) for c in cumulants)
    scale = k3 / (4.0 * k2)
    dof = 8.0 * k2**3 / k3**2
    return k1 - scale * dof, scale, dof


def pearson_sf(x: float, cumulants) -> float:
    """P(Q > x) for Q a weighted sum of chi-square variables with these three cumulants (Pearson's
    three-moment approximation, module docstring: exact for chi-square itself)."""
    import scipy.special

    shift, scale, dof = pearson(cumulants)
    return float(scipy.special.chdtrc(dof, max((x - shift) / scale, 0.0)))


def pearson_isf(level: float, cumulants) -> float:
    """The x with `pearson_sf`(x) = level."""
    import scipy.special

    shift, scale, dof = pearson(cumulants)
    return float(shift + scale * scipy.special.chdtri(dof, level))
