"""Gaussian log densities of the Gaussian-process family (nats).

- the exact GP marginal likelihood of residuals y (n, outputs), each output an independent
  N(0, K + noise^2 I): at given hyperparameters (`exact_log_likelihood`) and, with its analytic
  gradient in the log hyperparameters, as the objective of the hyperparameter fits
  (`negative_log_marginal_likelihood`);
- independent noise N(0, sigma^2) per component at sigma's maximum likelihood (`iid_log_likelihood`);
- the evidence of a linear model y = J theta + e, e ~ N(0, S) with any dense covariance S and
  theta ~ N(0, 1 / precision) integrated (`dense_log_evidence`); with S = C (x) I3, the three
  axes sharing C, by n x n factors, and its gradient in the hyperparameters of C
  (`kron_log_evidence_and_gradient`); and with S = noise^2 I + Phi diag(v) Phi^T for fixed
  features Phi, from sums computed once, and its gradient (`feature_log_evidence`).

SI inside (m, rad).
"""

from __future__ import annotations

import math

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from .kernels import Hyperparameters, covariance_with_noise, shape_from_distances

LOG_2PI = math.log(2.0 * math.pi)


def _cholesky_log_likelihood(cov, y) -> tuple[float, tuple, np.ndarray]:
    """log N(y_a; 0, cov) summed over the outputs a of y (n, outputs), the Cholesky factor of cov
    (n, n) (scipy's cho_factor) and alpha = cov^-1 y (n, outputs). Raises LinAlgError when cov is
    not positive definite."""
    import scipy.linalg

    factor = scipy.linalg.cho_factor(cov, lower=True, check_finite=False)
    alpha = scipy.linalg.cho_solve(factor, y, check_finite=False)
    n, outputs = y.shape
    log_det = 2.0 * float(np.sum(np.log(np.diag(factor[0]))))
    return -0.5 * (float(np.sum(y * alpha)) + outputs * log_det + n * outputs * LOG_2PI), factor, alpha


def exact_log_likelihood(q, residuals, hyper: Hyperparameters) -> float:
    """log p(r) (nats) of residuals (n, 3) m at readings q (n, N) rad under the GP with `hyper`,
    each output an independent N(0, K + noise^2 I): dense Cholesky, O(n^3)."""
    return _cholesky_log_likelihood(covariance_with_noise(q, hyper), np.asarray(residuals, dtype=float))[0]


def _inverse_from_cholesky(lower: np.ndarray) -> np.ndarray:
    """The inverse (n, n) of L L^T from its lower Cholesky factor L (n, n) (LAPACK potri: half the
    work of solving against the identity, the gradient's costliest step)."""
    from scipy.linalg import lapack

    inverse, info = lapack.dpotri(lower, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"the covariance's inverse failed (LAPACK potri info {info})")
    return np.tril(inverse) + np.tril(inverse, -1).T


def negative_log_marginal_likelihood(
    log_params: np.ndarray, distances: np.ndarray, y: np.ndarray
) -> tuple[float, np.ndarray]:
    """-log p(y) of the exact GP and its gradient in (log l_j..., log s, log noise); distances
    (J, n, n) the per-joint 1 - cos differences (`kernels.circle_distances`), y (n, outputs).
    1e25 with a zero gradient where the covariance is not positive definite (the optimiser steps back)."""

    n_len = len(distances)
    weights = np.exp(-2.0 * log_params[:n_len])
    signal2, noise2 = math.exp(2.0 * log_params[n_len]), math.exp(2.0 * log_params[n_len + 1])
    shape = shape_from_distances(distances, weights)
    cov = signal2 * shape
    cov[np.diag_indices_from(cov)] += noise2
    try:
        log_likelihood, factor, alpha = _cholesky_log_likelihood(cov, y)
        inverse = _inverse_from_cholesky(factor[0])
    except np.linalg.LinAlgError:
        return 1e25, np.zeros_like(log_params)
    outputs = y.shape[1]
    w = alpha @ alpha.T - outputs * inverse  # d log p = 1/2 tr(W dK)
    g = w * (signal2 * shape)
    gradient = np.empty_like(log_params)
    gradient[:n_len] = weights * np.tensordot(distances, g, axes=((1, 2), (0, 1)))  # 1/2 * 2 w_j sum(D_j G)
    gradient[n_len] = float(np.sum(g))
    gradient[n_len + 1] = noise2 * float(np.trace(w))
    return -log_likelihood, -gradient


def iid_log_likelihood(residuals) -> float:
    """log p of residuals (n, 3) m under N(0, sigma^2) per component at sigma's maximum likelihood."""
    r = np.asarray(residuals, dtype=float)
    k = r.size
    return -0.5 * k * (LOG_2PI + math.log(float(np.sum(r * r)) / k) + 1.0)


def integrated_log_evidence(quadratic: float, a, b, log_det_covariance: float, size: int, precision) -> float:
    """log Z of data y (size,) = J theta + e, e ~ N(0, C), theta ~ N(0, 1 / precision) (P,) (0: flat,
    its improper constant left out), from quadratic = y^T C^-1 y, A = J^T C^-1 J + diag(precision)
    (P, P), b = J^T C^-1 y (P,) and log|C|, however C was factored. Raises LinAlgError when A is not
    positive definite (a flat parameter the data do not determine)."""
    precision = np.asarray(precision, dtype=float)
    sign, log_det_a = np.linalg.slogdet(a)
    if sign <= 0:
        raise np.linalg.LinAlgError("a parameter without prior is not determined by the data with the GP present")
    proper = precision > 0
    return float(
        -0.5 * quadratic
        + 0.5 * b @ np.linalg.solve(a, b)
        - 0.5 * log_det_covariance
        - 0.5 * log_det_a
        - 0.5 * size * LOG_2PI
        + 0.5 * np.sum(np.log(precision[proper]))
        + 0.5 * int((~proper).sum()) * LOG_2PI
    )


def _dense_log_evidence(factor, y, jacobian, precision) -> float:
    """`dense_log_evidence` from the Cholesky factor (scipy's cho_factor) of the covariance."""
    import scipy.linalg

    solved_j, solved_y = scipy.linalg.cho_solve(factor, jacobian), scipy.linalg.cho_solve(factor, y)
    a = jacobian.T @ solved_j + np.diag(precision)
    log_det = 2.0 * float(np.sum(np.log(np.diag(factor[0]))))
    return integrated_log_evidence(float(y @ solved_y), a, jacobian.T @ solved_y, log_det, len(y), precision)


def dense_log_evidence(y, jacobian, precision, covariance) -> float:
    """log Z of y (m,) = J theta + e with e ~ N(0, covariance (m, m)) and theta (P,) ~ N(0, 1 /
    precision) (precision (P,), 0: flat, its improper constant left out: common to every model of
    the same flat blocks), J (m, P). The general form of `with_parameters.with_gp`'s evidence, for
    noise that is not the same on the three axes."""
    import scipy.linalg

    y, jacobian, precision = (np.asarray(a, dtype=float) for a in (y, jacobian, precision))
    return _dense_log_evidence(scipy.linalg.cho_factor(covariance, lower=True), y, jacobian, precision)


def feature_log_evidence(gram, projected, yy: float, size: int, precision, variances, noise: float):
    """log Z of data y (size,) = J theta + Phi w + e, e ~ N(0, noise^2 I), theta ~ N(0, 1 / precision)
    (P,) (0: flat, its improper constant left out) and w ~ N(0, diag(variances)) (F,): Bayesian
    linear regression on fixed features, from the sums X^T X = gram (P + F, P + F), X^T y = projected
    (P + F,) and y^T y = yy of X = [J, Phi], computed once whatever the hyperparameters, so that each
    evaluation costs O((P + F)^3) and none grows with the rows. A feature of variance 0 is left out.
    Returns (log Z, d log Z / d log variances (F,), d log Z / d log noise)."""
    import scipy.linalg

    precision, variances = np.asarray(precision, dtype=float), np.asarray(variances, dtype=float)
    p = len(precision)
    kept = np.concatenate([np.arange(p), p + np.flatnonzero(variances > 0)])
    weights = np.concatenate([precision, 1.0 / variances[variances > 0]])
    tau = 1.0 / noise**2
    g, b = gram[np.ix_(kept, kept)], projected[kept]
    a = tau * g + np.diag(weights)
    value = integrated_log_evidence(tau * yy, a, tau * b, size * math.log(noise**2), size, weights)
    covariance = scipy.linalg.cho_solve(scipy.linalg.cho_factor(a, lower=True), np.eye(len(kept)))
    mean = tau * covariance @ b
    # d log Z / d (prior precision d_k) = (1 / d_k - Sigma_kk - mu_k^2) / 2; d_k = 1 / v_k
    by_weight = 0.5 * (1.0 / weights[p:] - np.diag(covariance)[p:] - mean[p:] ** 2)
    by_log_variance = np.zeros(len(variances))
    by_log_variance[variances > 0] = -weights[p:] * by_weight
    misfit = yy - 2.0 * b @ mean + mean @ g @ mean  # |y - X mu|^2
    by_tau = -0.5 * misfit + 0.5 * size / tau - 0.5 * float(np.sum(covariance * g))
    return value, by_log_variance, -2.0 * tau * by_tau


def kron_log_evidence_and_gradient(y, jacobian, precision, covariance, derivatives) -> tuple[float, np.ndarray]:
    """`dense_log_evidence` of residuals y (n, 3) whose three axes share the covariance C (n, n)
    (S = C (x) I3, the free GP's), J = jacobian (n, 3, P), and its gradient with respect to the
    hyperparameters whose derivatives dC (k, n, n) are given: 1/2 sum(W * dC), W = sum_a alpha_a
    alpha_a^T - 3 C^-1 + sum_a (C^-1 J_a) A^-1 (C^-1 J_a)^T. n x n factors, not 3n x 3n."""
    import scipy.linalg

    y, jacobian, precision = (np.asarray(a, dtype=float) for a in (y, jacobian, precision))
    factor = scipy.linalg.cho_factor(covariance, lower=True)
    inverse = scipy.linalg.cho_solve(factor, np.eye(len(y)))
    solved_j = np.einsum("nm,map->nap", inverse, jacobian)  # C^-1 J_a per axis
    solved_y = inverse @ y
    a = np.einsum("nap,naq->pq", jacobian, solved_j) + np.diag(precision)
    b = np.einsum("nap,na->p", jacobian, solved_y)
    log_det = 2.0 * float(np.sum(np.log(np.diag(factor[0]))))
    value = integrated_log_evidence(float(np.sum(y * solved_y)), a, b, 3.0 * log_det, 3 * len(y), precision)
    mean = np.linalg.solve(a, b)
    alpha = solved_y - np.einsum("nap,p->na", solved_j, mean)
    n = len(y)
    flat = solved_j.reshape(n, -1)
    w = alpha @ alpha.T - 3.0 * inverse + (solved_j @ np.linalg.inv(a)).reshape(n, -1) @ flat.T
    return value, np.array([0.5 * float(np.sum(w * d)) for d in derivatives])
