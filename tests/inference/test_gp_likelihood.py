"""The Gaussian log densities of the GP family (`remaster.inference.gp.likelihood`) against known
answers: the exact likelihood is the dense multivariate normal, the marginal likelihood's and the
dense evidence's gradients are their derivatives (finite differences)."""

import math

import numpy as np
import pytest
import scipy.optimize
import scipy.stats

from remaster.inference.gp import likelihood
from remaster.inference.gp.kernels import Hyperparameters, circle_distances, kernel

from .test_gp_residual import readings, smooth_residual

NOISE = 3e-5


def test_the_exact_likelihood_is_the_dense_multivariate_normal():
    rng = np.random.default_rng(1)
    q = rng.uniform(-1.5, 1.5, (80, 3))
    hyper = Hyperparameters(np.array([0.4, 0.7, np.inf]), 1e-4, NOISE)
    y = rng.normal(0.0, 5e-5, (len(q), 3))
    cov = kernel(q, q, hyper) + NOISE**2 * np.eye(len(q))
    dense = sum(scipy.stats.multivariate_normal(np.zeros(len(q)), cov).logpdf(y[:, i]) for i in range(3))
    assert likelihood.exact_log_likelihood(q, y, hyper) == pytest.approx(dense, rel=1e-10)


def test_the_marginal_likelihood_gradient_is_the_derivative():
    rng = np.random.default_rng(9)
    q = readings(rng, 60)[:, [0, 1, 3]]
    y = smooth_residual(np.insert(q, [2, 2, 2, 2], 0.0, axis=1)[:, :7]) / 1e-4 + rng.normal(0, 0.2, (60, 3))
    distances = circle_distances(q)
    x = np.log([0.7, 1.3, 0.9, 0.8, 0.3])
    value, gradient = likelihood.negative_log_marginal_likelihood(x, distances, y)
    numeric = scipy.optimize.approx_fprime(
        x, lambda v: likelihood.negative_log_marginal_likelihood(v, distances, y)[0], 1e-6
    )
    np.testing.assert_allclose(gradient, numeric, rtol=1e-4, atol=1e-4)


def test_the_dense_evidence_gradient_is_its_derivative():
    rng = np.random.default_rng(5)
    m, p = 30, 3
    jacobian, y = rng.normal(size=(m, p)), rng.normal(size=m)
    precision = np.array([0.0, 2.0, 0.5])
    basis = [rng.normal(size=(m, m)) for _ in range(2)]
    basis = [b @ b.T for b in basis]

    def covariance(x):
        return np.exp(x[0]) * basis[0] + np.exp(x[1]) * basis[1] + np.eye(m)

    x = np.array([-0.3, 0.4])
    value, gradient = likelihood.dense_log_evidence_and_gradient(
        y, jacobian, precision, covariance(x), [np.exp(x[0]) * basis[0], np.exp(x[1]) * basis[1]]
    )
    for k in range(2):
        step = np.zeros(2)
        step[k] = 1e-6
        up = likelihood.dense_log_evidence_and_gradient(y, jacobian, precision, covariance(x + step), [])[0]
        down = likelihood.dense_log_evidence_and_gradient(y, jacobian, precision, covariance(x - step), [])[0]
        assert math.isclose(gradient[k], (up - down) / 2e-6, rel_tol=1e-5)
    assert math.isfinite(value)
