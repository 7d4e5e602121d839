"""The least-squares mode of a residual function and the paper's Laplace approximation about it.

`least_squares_mode` is the mode of both Laplace approximations (the paper fit's and the block
models' under their priors, `evidence.posterior_mode`); `least_squares_laplace` is the paper's
(flat prior on theta, sigma integrated out), the start and scale of its samplers, and raises
`NotIdentifiable` when the data do not determine some parameter combinations.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from ..errors import RemasterError
from .identifiability import RCOND, undetermined_directions  # the one test: the analysis's and the fit's


class NotIdentifiable(RemasterError, ValueError):
    """The data do not determine some parameter combinations: J^T J is (numerically) singular.

    `combinations` lists, per undetermined direction, {parameter name: weight} of its main parts.
    """

    def __init__(self, message: str, combinations: list[dict[str, float]]):
        self.combinations = combinations
        super().__init__(message)


@dataclass(frozen=True, eq=False)
class LaplaceResult:
    """Least-squares fit of the P-1 model parameters and the Laplace (Gaussian) approximation.

    theta_map (P-1,) SI; covariance (P-1, P-1) = s^2 (J^T J)^-1 with s^2 = SS / (k - (P-1)),
    SS the sum of squared residuals over k residual components; cost = SS / 2 (scipy's
    convention, kept for comparison with scipy's output); jacobian_singular_values of J with
    columns in step units (J * scale), largest first.

    Noise (k components i.i.d. N(0, sigma^2)): sigma_map = sqrt(SS / k), the maximum-likelihood
    value. Under the paper's posterior sigma^-(k+2) exp(-SS / 2 sigma^2) with the model linearised
    at theta_map (flat prior on theta integrated out), sigma^2 ~ SS / chi^2_nu, nu = k - (P-1) + 1,
    so exactly
        sigma_mean = sqrt(SS / 2) Gamma((nu - 1) / 2) / Gamma(nu / 2)
        sigma_std  = sqrt(SS / (nu - 2) - sigma_mean^2)   (~ sigma / sqrt(2 nu) ~ sigma / sqrt(2k)).
    sigma_mean / sigma_std are what an MCMC run of the paper's posterior should reproduce.
    """

    theta_map: np.ndarray
    covariance: np.ndarray
    sigma_map: float
    sigma_mean: float
    sigma_std: float
    cost: float
    jacobian_singular_values: np.ndarray
    n_residuals: int
    names: tuple[str, ...]

    @property
    def std(self) -> np.ndarray:
        """(P-1,) Laplace standard deviations of the model parameters, SI."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def theta_start(self) -> np.ndarray:
        """(P,) model parameters and sigma_map: a start for the samplers."""
        return np.append(self.theta_map, self.sigma_map)

    def full_covariance(self) -> np.ndarray:
        """(P, P) covariance including sigma (independent of theta at the linearisation point)."""
        p = len(self.theta_map)
        out = np.zeros((p + 1, p + 1))
        out[:p, :p] = self.covariance
        out[p, p] = self.sigma_std**2
        return out

    def moments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(mean, std, mcse), each (P,), for `diagnostics.cross_check`. mcse is 0: no Monte Carlo."""
        mean = np.append(self.theta_map, self.sigma_mean)
        std = np.append(self.std, self.sigma_std)
        return mean, std, np.zeros_like(mean)


def _undetermined(vt: np.ndarray, small: np.ndarray, names: Sequence[str]) -> list[dict[str, float]]:
    """For each null direction (row of V^T in step units), its parameters with weight >= 0.1."""
    out = []
    for row in vt[small]:
        row = row / row[np.argmax(np.abs(row))]
        out.append({names[i]: float(row[i]) for i in np.flatnonzero(np.abs(row) >= 0.1)})
    return out


def least_squares_mode(
    residuals: Callable[[np.ndarray], np.ndarray],
    theta0,
    scale,
    jacobian="2-point",
    method: str = "trf",
    starts=(),
):
    """The minimum of the sum of squared residuals(theta) (k,) over theta (P,) SI: scipy's least
    squares from theta0 (P,) to tolerances of 1e-12, scale (P,) SI step units as its x_scale;
    jacobian: a callable theta -> (k, P), or scipy's "2-point" forward differences; method: scipy's
    "trf" or "lm" (MINPACK: no SVD of the whole Jacobian per step). starts (m, P): further starts,
    the best of all kept. Returns scipy's OptimizeResult (x, cost = SS / 2, jac at x). The mode of
    both Laplace approximations: the paper fit's (`least_squares_laplace`) and the block models'
    under their priors (`evidence.posterior_mode`)."""
    import scipy.optimize

    fits = [
        scipy.optimize.least_squares(
            residuals, x, jac=jacobian, x_scale=scale, method=method, xtol=1e-12, ftol=1e-12, gtol=1e-12
        )
        for x in [theta0, *starts]
    ]
    return min(fits, key=lambda f: f.cost)


def least_squares_laplace(
    residuals: Callable[[np.ndarray], np.ndarray],
    theta0,
    scale,
    rng=None,
    names: Sequence[str] | None = None,
    jacobian=None,
    n_restarts: int = 0,
    restart_spread: float = 1.0,
    rcond: float = RCOND,
) -> LaplaceResult:
    """Minimise the sum of squared residuals(theta) (k,) over theta (P-1,) SI; Laplace covariance.

    scale (P-1,) SI step units: used as scipy's x_scale and to make singular values unit-free.
    jacobian: optional callable theta -> (k, P-1); finite differences otherwise. n_restarts > 0
    also starts from theta0 + restart_spread * scale * N(0, 1) (needs rng) and keeps the best.

    Raises NotIdentifiable naming the parameter combinations whose singular value of J * scale is
    below rcond * the largest: their variance would be (near) infinite, and a pseudo-inverse would
    silently report a finite one. See `LaplaceResult` for the sigma formulas.

    Not `evidence.laplace_at`, which approximates another posterior for another use: this one is the
    paper's (flat prior on theta, sigma^-(k+2), any residual function), with sigma integrated out:
    covariance s^2 (J^T J)^-1 at s^2 = SS / (k - (P-1)), sigma's exact marginal mean and std, the
    SVD test above, no evidence: the start and scale of the paper's samplers. `laplace_at` takes a
    block model's joint mode in (theta, log sigma) under its priors and noise shape, inverts the
    (P + 1)-square Hessian there (sigma^2 at SS / (k + 1), sigma correlated with theta) and gives
    the log evidence the loop compares models by. On the paper's model at the same mode, this
    theta covariance is that one's times (k + 1) / (k - P + 1).
    """
    from scipy.special import gammaln

    theta0 = np.asarray(theta0, dtype=float)
    scale = np.broadcast_to(np.asarray(scale, dtype=float), theta0.shape)
    names = tuple(names) if names is not None else tuple(f"theta[{i}]" for i in range(len(theta0)))
    starts = []
    if n_restarts:
        if rng is None:
            raise ValueError("n_restarts > 0 needs rng")
        starts = list(theta0 + restart_spread * scale * rng.standard_normal((n_restarts, len(theta0))))
    fit = least_squares_mode(residuals, theta0, scale, "2-point" if jacobian is None else jacobian, "trf", starts)
    r = np.asarray(residuals(fit.x), dtype=float).ravel()
    k, m = r.size, len(theta0)
    sum_squares = float(r @ r)  # scipy's fit.cost is HALF of this
    if k <= m + 2:
        raise ValueError(f"{k} residuals cannot determine {m} parameters and sigma (need k > P + 1)")
    j = np.asarray(jacobian(fit.x) if jacobian is not None else fit.jac, dtype=float).reshape(k, m)
    # SVD of J in step units: a unit-free conditioning test; cov = D (J_s^T J_s)^-1 D s^2.
    singular, vt, small = undetermined_directions(j, scale, rcond)
    if small.any():
        combos = _undetermined(vt, small, names)
        text = "; ".join(" + ".join(f"{w:+.3g}*{n}" for n, w in c.items()) for c in combos)
        raise NotIdentifiable(
            f"the data do not determine {int(small.sum())} parameter combination(s) (singular values of "
            f"J in step units {singular[small]} < {rcond:g} x {singular[0]:.3g}): {text}. "
            f"Fix one parameter of each combination or add data that separates them.",
            combos,
        )
    s2 = sum_squares / (k - m)
    inverse = (vt.T / singular**2) @ vt
    covariance = s2 * inverse * np.outer(scale, scale)
    nu = k - m + 1
    sigma_mean = math.sqrt(sum_squares / 2) * math.exp(gammaln((nu - 1) / 2) - gammaln(nu / 2))
    sigma_std = math.sqrt(max(sum_squares / (nu - 2) - sigma_mean**2, 0.0))
    return LaplaceResult(
        theta_map=fit.x.copy(),
        covariance=covariance,
        sigma_map=math.sqrt(sum_squares / k),
        sigma_mean=sigma_mean,
        sigma_std=sigma_std,
        cost=float(fit.cost),
        jacobian_singular_values=singular,
        n_residuals=k,
        names=names,
    )
