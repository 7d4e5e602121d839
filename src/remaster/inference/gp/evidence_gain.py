"""The residual GP's evidence on the same footing as the parametric candidates' Laplace evidence.

The question the loop asks of the GP: are the current model's residuals r (n, 3) m (robot frame)
better explained by  r = g(q) + e  (g the GP of `residual`, e ~ N(0, noise^2 I3)) than by
independent noise  r = e,  e ~ N(0, sigma^2 I3)?  Both models are scored by their marginal
likelihood with every parameter integrated, the same way `remaster.inference.evidence.posterior_mode`
scores a parametric candidate:

- iid:  sigma has Jeffreys' prior (flat in u = log sigma, improper) and is integrated by a Laplace
  step in u:  log Z0 = log L(sigma_ML) + 1/2 log 2 pi - 1/2 log(2 k),  k = 3n.
- GP:   x = (log l_j for each turned joint, log s, log noise); log noise has the same flat prior as
  log sigma (its improper constant cancels in the difference), log s ~ N(log rms(r), 2^2) and
  log l_j ~ N(log range_j, 2^2) (proper; range_j the measured range of joint j, clipped to the
  lengthscale bounds: a priori the residual is as large as it is and varies about once over what
  was measured, within a factor e^2 ~ 7 either way at one std). The hyperparameters are integrated
  by a Laplace step in x at the mode of  log p(r | x) + log prior(x):
      log Z1 = log p(r | x*) + log prior(x*) + (d / 2) log 2 pi - 1/2 log det H,
  H the Hessian of the negative log posterior in x (central differences of its analytic gradient).

The mode x* and H are those of at most mode_rows evenly spaced rows (the hyperparameter fit's
subset, so the search costs O(mode_rows^3) per step), the likelihood part of H scaled by
n / mode_rows (it grows with the rows). log p(r | x*) is then taken on every row: the exact GP
marginal likelihood (Cholesky, O(n^3)) when n <= exact_rows, above that Titsias' (2009) collapsed
variational lower bound through the inducing inputs (the DTC likelihood less tr(K - Q) /
(2 noise^2) per output). x* is the mode of the subset's posterior, not of all rows', and the bound
is below the exact value: both make the GP's evidence an understatement, never a flattery.

gain = log Z1 - log Z0. The parametric parameters stay at the current mode in both models: their
Occam factor is common and cancels, which is what "same footing" means here (same residuals,
same noise model and prior, every parameter integrated the same way).

SI inside (m, rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from .kernels import LENGTH_BOUNDS, Hyperparameters, circle_distances, turned_joints
from .likelihood import LOG_2PI, exact_log_likelihood, iid_log_likelihood, negative_log_marginal_likelihood
from .residual import INDUCING, NOISE_BOUNDS, SIGNAL_BOUNDS, SUBSET, evenly_spaced, titsias_bound

EXACT_ROWS = 3000  # rows up to which the evidence is the exact marginal likelihood
LOG_PRIOR_STD = 2.0  # prior std of log s and of each log l_j
HESSIAN_STEP = 1e-3  # in the log hyperparameters, for the central differences of the gradient


def iid_log_evidence(residuals) -> float:
    """log Z0 (nats): residuals (n, 3) m as N(0, sigma^2) per component, sigma under Jeffreys'
    prior integrated by a Laplace step in log sigma (module docstring)."""
    k = np.asarray(residuals).size
    return iid_log_likelihood(residuals) + 0.5 * LOG_2PI - 0.5 * math.log(2.0 * k)


def _log_prior(x, prior_mean, prior_std) -> tuple[float, np.ndarray]:
    """log prior (nats) of x = (log l_j..., log s, log noise): independent normals on all but the
    noise (flat), and z (d - 1,) each one's distance from its mean in prior stds."""
    z = (x[:-1] - prior_mean) / prior_std
    return -float(np.sum(0.5 * z**2 + np.log(prior_std) + 0.5 * LOG_2PI)), z


def _negative_log_posterior(x, distances, y, prior_mean, prior_std) -> tuple[float, np.ndarray]:
    """-(log p(y | x) + log prior(x)) and its gradient in x = (log l_j..., log s, log noise), y (n, 3)
    in units of rms(r), distances (J, n, n) the turned joints' 1 - cos differences: the exact GP's
    likelihood is the one the hyperparameter fit maximizes (`residual.fit_hyperparameters`); the
    noise has no prior term (flat in log noise)."""
    value, gradient = negative_log_marginal_likelihood(x, distances, y)
    log_prior, z = _log_prior(x, prior_mean, prior_std)
    value -= log_prior
    gradient = np.array(gradient, dtype=float)
    gradient[:-1] += z / prior_std
    return value, gradient


@dataclass(frozen=True)
class GPEvidence:
    """The GP's evidence against independent noise (module docstring): gain (nats) = log Z1 - log Z0;
    method 'exact' or 'titsias'; rows_for_mode: the rows whose exact posterior gives the mode and H;
    mode: the hyperparameters at the evidence's mode; occam (nats): (d/2) log 2 pi - 1/2 log det H
    + log prior(x*); dtc_gain: the former measure (DTC log likelihood at the plug-in hyperparameters
    less the iid maximum likelihood less 1/2 log(3n) per hyperparameter beyond the noise), kept for
    comparison."""

    gain: float
    log_evidence_gp: float
    log_evidence_iid: float
    log_likelihood: float
    occam: float
    method: str
    rows_for_mode: int
    mode: Hyperparameters
    at_bound: bool
    dtc_gain: float | None = None

    def report(self) -> dict:
        return {
            "log_evidence_gain": self.gain,
            "log_evidence_gp": self.log_evidence_gp,
            "log_evidence_iid": self.log_evidence_iid,
            "log_likelihood_at_mode": self.log_likelihood,
            "occam_nats": self.occam,
            "method": self.method,
            "rows_for_mode": self.rows_for_mode,
            "mode": self.mode.report(),
            "mode_at_bound": self.at_bound,
            "dtc_gain_former": self.dtc_gain,
        }


def log_evidence_gain(
    q,
    residuals,
    hyper: Hyperparameters,
    exact_rows: int = EXACT_ROWS,
    inducing: int = INDUCING,
    mode_rows: int = SUBSET,
) -> GPEvidence:
    """The GP's log evidence gain over independent noise (module docstring) for readings q (n, N)
    rad and residuals (n, 3) m; hyper: the fitted (plug-in) hyperparameters, the mode search's start;
    mode_rows: the evenly spaced rows whose exact posterior gives the mode and H (O(mode_rows^3)
    per step of the search)."""
    import scipy.optimize

    q, y = np.asarray(q, dtype=float), np.asarray(residuals, dtype=float)
    n = len(q)
    unit = float(np.sqrt(np.mean(y**2))) or 1.0
    turned = turned_joints(q)
    n_len = int(turned.sum())
    span = np.clip(np.ptp(q, axis=0)[turned], *LENGTH_BOUNDS)
    prior_mean = np.concatenate([np.log(span), [0.0]])  # log l_j, log (s / unit)
    prior_std = np.full(n_len + 1, LOG_PRIOR_STD)
    rows = evenly_spaced(n, mode_rows)
    distances = circle_distances(q[rows][:, turned])
    y_e = y[rows] / unit
    lengths = np.where(np.isfinite(hyper.lengthscales), hyper.lengthscales, LENGTH_BOUNDS[1])[turned]
    x0 = np.concatenate(
        [
            np.log(np.clip(lengths, *LENGTH_BOUNDS)),
            [math.log(np.clip(hyper.signal_std / unit, *SIGNAL_BOUNDS))],
            [math.log(np.clip(hyper.noise_std / unit, *NOISE_BOUNDS))],
        ]
    )
    bounds = [tuple(np.log(LENGTH_BOUNDS))] * n_len + [tuple(np.log(SIGNAL_BOUNDS)), tuple(np.log(NOISE_BOUNDS))]
    args = (distances, y_e, prior_mean, prior_std)
    best = scipy.optimize.minimize(_negative_log_posterior, x0, args=args, jac=True, method="L-BFGS-B", bounds=bounds)
    x = best.x
    lower, upper = np.array(bounds).T
    at_bound = bool(np.any((x - lower < 1e-3) | (upper - x < 1e-3)))
    d = len(x)
    hessian = np.empty((d, d))
    for i in range(d):
        step = np.zeros(d)
        step[i] = HESSIAN_STEP
        hessian[i] = (_negative_log_posterior(x + step, *args)[1] - _negative_log_posterior(x - step, *args)[1]) / (
            2.0 * HESSIAN_STEP
        )
    hessian = 0.5 * (hessian + hessian.T)
    precision = np.concatenate([1.0 / prior_std**2, [0.0]])
    likelihood_part = hessian - np.diag(precision)
    if len(rows) < n:  # the likelihood's curvature grows with the rows
        likelihood_part *= n / len(rows)
    # the posterior curves at least as much as the prior in every direction: a negative eigenvalue
    # of a noisy difference (or a mode on a bound) is clipped there, never a negative determinant
    values, vectors = np.linalg.eigh(likelihood_part)
    floor = np.diag(precision).copy()
    hessian = vectors @ np.diag(np.maximum(values, 0.0)) @ vectors.T + floor
    hessian[-1, -1] = max(hessian[-1, -1], 1e-6)  # log noise: flat prior, the data always fix it
    sign, log_det = np.linalg.slogdet(hessian)
    log_prior, _ = _log_prior(x, prior_mean, prior_std)
    all_lengths = np.full(q.shape[1], np.inf)
    all_lengths[turned] = np.exp(x[:n_len])
    mode = Hyperparameters(all_lengths, unit * math.exp(x[n_len]), unit * math.exp(x[n_len + 1]))
    if n <= exact_rows:
        method = "exact"
        log_likelihood = exact_log_likelihood(q, y, mode)
    else:
        method = "titsias"
        log_likelihood = titsias_bound(q, y, mode, inducing)
    occam = log_prior + 0.5 * d * LOG_2PI - 0.5 * log_det
    log_z1 = log_likelihood + occam
    log_z0 = iid_log_evidence(y)
    return GPEvidence(
        float(log_z1 - log_z0),
        float(log_z1),
        float(log_z0),
        float(log_likelihood),
        float(occam),
        method,
        int(len(rows)),
        mode,
        at_bound,
    )
