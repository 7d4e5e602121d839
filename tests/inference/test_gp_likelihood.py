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


def test_the_shared_axes_evidence_and_its_gradient_are_the_dense_ones():
    """kron_log_evidence_and_gradient: the dense evidence of C (x) I3, and its gradient the
    derivative in the log hyperparameters (finite differences)."""
    rng = np.random.default_rng(5)
    n, p = 30, 3
    q = rng.uniform(-2.0, 2.0, (n, 2))
    jacobian, y = rng.normal(size=(n, 3, p)), rng.normal(size=(n, 3))
    precision = np.array([0.0, 2.0, 0.5])
    distances = circle_distances(q)

    def terms(x):
        base = math.exp(2 * x[2]) * np.exp(-np.tensordot(np.exp(-2 * x[:2]), distances, axes=1))
        derivatives = [base * 2 * math.exp(-2 * x[j]) * distances[j] for j in range(2)]
        return base + math.exp(2 * x[3]) * np.eye(n), derivatives + [2 * base, 2 * math.exp(2 * x[3]) * np.eye(n)]

    x = np.array([0.1, -0.4, 0.2, -0.6])
    value, gradient = likelihood.kron_log_evidence_and_gradient(y, jacobian, precision, *terms(x))
    dense = likelihood.dense_log_evidence(
        y.ravel(), jacobian.reshape(3 * n, p), precision, np.kron(terms(x)[0], np.eye(3))
    )
    assert value == pytest.approx(dense, rel=1e-12)
    for k in range(4):
        step = 1e-6 * np.eye(4)[k]
        up = likelihood.kron_log_evidence_and_gradient(y, jacobian, precision, terms(x + step)[0], [])[0]
        down = likelihood.kron_log_evidence_and_gradient(y, jacobian, precision, terms(x - step)[0], [])[0]
        assert math.isclose(gradient[k], (up - down) / 2e-6, rel_tol=1e-5)


def test_the_feature_evidence_and_its_gradient_are_the_dense_ones():
    """feature_log_evidence: the dense evidence of noise^2 I + Phi diag(v) Phi^T from its sums (a
    feature of variance 0 left out), its gradient the derivative in log v and log noise."""
    rng = np.random.default_rng(6)
    m, p, f = 60, 3, 5
    jacobian, features, y = rng.normal(size=(m, p)), rng.normal(size=(m, f)), rng.normal(size=m)
    precision = np.array([0.0, 2.0, 0.5])
    both = np.hstack([jacobian, features])
    sums = (both.T @ both, both.T @ y, float(y @ y), m, precision)

    def evidence(log_v, log_noise):
        return likelihood.feature_log_evidence(*sums, np.exp(log_v), math.exp(log_noise))

    log_v, log_noise = np.log(rng.uniform(0.2, 2.0, f)), -0.3
    value, by_v, by_noise = evidence(log_v, log_noise)
    covariance = features @ np.diag(np.exp(log_v)) @ features.T + math.exp(2 * log_noise) * np.eye(m)
    assert value == pytest.approx(likelihood.dense_log_evidence(y, jacobian, precision, covariance), rel=1e-12)
    for k in range(f):
        step = 1e-6 * np.eye(f)[k]
        assert math.isclose(
            by_v[k], (evidence(log_v + step, log_noise)[0] - evidence(log_v - step, log_noise)[0]) / 2e-6, rel_tol=1e-5
        )
    assert math.isclose(
        by_noise, (evidence(log_v, log_noise + 1e-6)[0] - evidence(log_v, log_noise - 1e-6)[0]) / 2e-6, rel_tol=1e-5
    )
    without = likelihood.feature_log_evidence(*sums, np.r_[np.exp(log_v[:-1]), 0.0], math.exp(log_noise))[0]
    covariance = features[:, :-1] @ np.diag(np.exp(log_v[:-1])) @ features[:, :-1].T + math.exp(2 * log_noise) * np.eye(
        m
    )
    assert without == pytest.approx(likelihood.dense_log_evidence(y, jacobian, precision, covariance), rel=1e-12)
