"""A linear model with the residual GP present (`remaster.inference.gp.with_parameters`) against closed forms it
does not use: the evidence is the Gaussian density of the data under the model's marginal covariance
(scipy), a flat prior is the limit of wide ones, and the cross-validation is kriging written out with
dense matrices; with a vanishing GP it is the parametric model's own generalised least squares."""

import math
from types import SimpleNamespace

import numpy as np
import scipy.stats

from remaster.inference.gp import with_parameters
from remaster.inference.gp.kernels import Hyperparameters, kernel


def linear_case(rng, n=40, prior_std=(np.inf, 2e-3, 5e-4), signal=3e-5, noise=1e-5):
    """A linear 'model' of n points: y = J theta + g(q) + e, in the shape of a PosteriorMode."""
    q = rng.uniform(-2.0, 2.0, (n, 2))
    jacobian = rng.normal(size=(3 * n, len(prior_std))) * 0.3
    hyper = Hyperparameters(np.array([0.8, 1.5]), signal, noise)
    covariance = np.kron(kernel(q, q, hyper), np.eye(3)) + noise**2 * np.eye(3 * n)
    theta_true = np.array([1e-3, 1e-3, -4e-4])
    y = jacobian @ theta_true + rng.multivariate_normal(np.zeros(3 * n), covariance)
    theta_mode = theta_true + 1e-4  # any linearisation point: the model is linear
    prior_std = np.asarray(prior_std, dtype=float)
    model = SimpleNamespace(
        n_points=n,
        noise_log_det=0.0,
        whitened=lambda r: r,
        _prior_precision=np.where(np.isfinite(prior_std), 1.0 / prior_std**2, 0.0),
    )
    residuals = (y - jacobian @ theta_mode).reshape(n, 3)
    mode = SimpleNamespace(model=model, theta=theta_mode, jacobian=jacobian, residuals=residuals)
    return mode, q, hyper, y, covariance, prior_std


def test_the_evidence_is_the_marginal_density_of_the_data():
    mode, q, hyper, y, covariance, prior_std = linear_case(np.random.default_rng(1), prior_std=(1e-3, 2e-3, 5e-4))
    folds = np.arange(len(q)) % 4
    marginal = covariance + mode.jacobian @ np.diag(prior_std**2) @ mode.jacobian.T
    expected = scipy.stats.multivariate_normal(np.zeros(len(y)), marginal).logpdf(y)
    assert math.isclose(with_parameters.with_gp(mode, q, hyper, folds).log_evidence, expected, rel_tol=0, abs_tol=1e-6)


def test_a_flat_prior_is_the_limit_of_wide_ones():
    rng = np.random.default_rng(2)
    mode, q, hyper, *_ = linear_case(rng)
    folds = np.arange(len(q)) % 4
    flat = with_parameters.with_gp(mode, q, hyper, folds).log_evidence
    wide = 1e3  # prior std of the flat parameter
    mode.model._prior_precision[0] = 1.0 / wide**2
    proper = with_parameters.with_gp(mode, q, hyper, folds).log_evidence
    # Z_proper -> Z_flat N(0; 0, wide^2) as the prior widens: the flat constant is 1 / sqrt(2 pi) wide
    assert math.isclose(proper + math.log(wide) + 0.5 * math.log(2 * math.pi), flat, abs_tol=1e-6)


def test_the_cross_validation_is_kriging_with_the_parametric_trend():
    mode, q, hyper, y, covariance, prior_std = linear_case(np.random.default_rng(3))
    folds = np.arange(len(q)) % 4
    result = with_parameters.with_gp(mode, q, hyper, folds)
    precision = np.where(np.isfinite(prior_std), 1.0 / prior_std**2, 0.0)
    jacobian, n = mode.jacobian, len(q)
    for fold in range(4):
        held = np.repeat(folds == fold, 3)
        inverse = np.linalg.inv(covariance[np.ix_(~held, ~held)])
        j_t = jacobian[~held]
        theta = np.linalg.solve(j_t.T @ inverse @ j_t + np.diag(precision), j_t.T @ inverse @ y[~held])
        predicted = jacobian[held] @ theta + covariance[np.ix_(held, ~held)] @ inverse @ (y[~held] - j_t @ theta)
        mse = np.sum((y[held] - predicted) ** 2) / held.sum() * 3
        assert math.isclose(result.cv.mse[fold], mse, rel_tol=1e-8)
        assert result.cv.points[fold] == n // 4


def test_without_a_gp_the_parameters_are_the_least_squares_ones():
    mode, q, hyper, y, _, prior_std = linear_case(np.random.default_rng(4), signal=1e-12)
    result = with_parameters.with_gp(mode, q, hyper, np.arange(len(q)) % 4)
    precision = np.where(np.isfinite(prior_std), 1.0 / prior_std**2, 0.0) * hyper.noise_std**2
    j = mode.jacobian
    expected = np.linalg.solve(j.T @ j + np.diag(precision), j.T @ y)
    np.testing.assert_allclose(result.theta, expected, rtol=1e-6)
    covariance = np.linalg.inv(j.T @ j / hyper.noise_std**2 + np.diag(precision / hyper.noise_std**2))
    np.testing.assert_allclose(result.std, np.sqrt(np.diag(covariance)), rtol=1e-6)


def test_through_every_row_as_inducing_input_it_is_the_exact_form():
    """The inducing-input form with the rows themselves as inducing inputs has Q = K and no trace
    term: its evidence, parameters and held-out errors are the exact ones."""
    mode, q, hyper, *_ = linear_case(np.random.default_rng(5), prior_std=(1e-3, 2e-3, 5e-4))
    folds = np.arange(len(q)) % 4
    exact = with_parameters.with_gp(mode, q, hyper, folds)
    sparse = with_parameters.sparse_with_gp(mode, q, hyper, folds, inducing=len(q))
    assert exact.method == "exact" and sparse.method == "titsias"
    assert math.isclose(sparse.log_evidence, exact.log_evidence, rel_tol=0, abs_tol=1e-4)
    np.testing.assert_allclose(sparse.theta, exact.theta, rtol=1e-6)
    np.testing.assert_allclose(sparse.std, exact.std, rtol=1e-6)
    np.testing.assert_allclose(sparse.cv.mse, exact.cv.mse, rtol=1e-6)
    np.testing.assert_array_equal(sparse.cv.points, exact.cv.points)


def test_fewer_inducing_inputs_bound_the_evidence_from_below_and_approach_it():
    """Titsias' bound with theta integrated: below the exact log Z at every number of inducing
    inputs, closer with more of them; the held-out errors of a smooth GP are close at a third of the
    rows."""
    mode, q, hyper, *_ = linear_case(np.random.default_rng(6), n=150)
    folds = np.arange(len(q)) % 5
    exact = with_parameters.with_gp(mode, q, hyper, folds)
    bounds = [with_parameters.sparse_with_gp(mode, q, hyper, folds, inducing=m) for m in (10, 25, 50)]
    gaps = [exact.log_evidence - b.log_evidence for b in bounds]
    assert all(g > -1e-6 for g in gaps) and gaps[0] > gaps[1] > gaps[2]
    np.testing.assert_allclose(bounds[-1].cv.mse, exact.cv.mse, rtol=0.1)


def test_above_the_exact_size_the_inducing_form_is_taken(monkeypatch):
    mode, q, hyper, *_ = linear_case(np.random.default_rng(7))
    monkeypatch.setattr(with_parameters, "MAX_ROWS", 30)
    assert with_parameters.with_gp(mode, q, hyper, np.arange(len(q)) % 4).method == "titsias"


def _unit_shapes(rng, n):
    """(n, 3, 3) positive definite shapes of a range/transverse kind: 1 along a direction, 2-4 across."""
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    across = rng.uniform(2.0, 4.0, n)[:, None, None]
    outer = directions[:, :, None] * directions[:, None, :]
    return across * (np.eye(3) - outer) + outer


def test_the_shaped_noise_evidence_through_every_row_is_the_dense_one():
    """The noise-shape comparison's inducing form with the rows as inducing inputs is the dense
    density of the data at every noise scale; with fewer it stays below it."""
    rng = np.random.default_rng(8)
    mode, q, hyper, *_ = linear_case(rng, prior_std=(1e-3, 2e-3, 5e-4))
    shapes = _unit_shapes(rng, len(q))
    through_rows = with_parameters.ShapedNoiseEvidence(mode, q, hyper, shapes, inducing=len(q))
    fewer = with_parameters.ShapedNoiseEvidence(mode, q, hyper, shapes, inducing=8)
    for sigma in (5e-6, 1e-5, 3e-5):
        dense = with_parameters.noise_shape_log_evidence(mode, q, hyper, sigma**2 * shapes)
        assert math.isclose(through_rows(sigma), dense, rel_tol=0, abs_tol=1e-4)
        assert fewer(sigma) < dense
