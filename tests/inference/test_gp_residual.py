"""The residual Gaussian process (`remaster.inference.gp.residual`) against known answers: its
hyperparameters find the noise and the joints, its mean and variance are honest near the data and
return to the prior far from it, with every row inducing it is the exact GP, and Titsias' bound is
a lower bound on the exact likelihood."""

import dataclasses

import numpy as np
import pytest
from scipy import stats

from remaster.inference.gp import kernels, likelihood, residual
from remaster.inference.gp.kernels import Hyperparameters, kernel

NOISE = 2e-5


def smooth_residual(q):
    """A residual (n, 3) m that depends on joints 2 and 4 only."""
    return np.column_stack([3e-4 * np.sin(2 * q[:, 1]), 2e-4 * np.cos(q[:, 3] + q[:, 1]), 1e-4 * np.sin(3 * q[:, 3])])


def readings(rng, n, low=-2.0, high=2.0):
    q = rng.uniform(low, high, (n, 7))
    q[:, 2] = 0.0  # a joint the data never turn
    return q


@pytest.fixture(scope="module")
def learnt():
    rng = np.random.default_rng(5)
    q = readings(rng, 1500)
    y = smooth_residual(q) + rng.normal(0.0, NOISE, (len(q), 3))
    hyper = residual.fit_hyperparameters(q, y)
    return q, y, hyper, residual.ResidualGP(q, y, hyper)


def test_the_hyperparameters_find_the_noise_and_the_joints(learnt):
    q, _, hyper, _ = learnt
    assert hyper.noise_std == pytest.approx(NOISE, rel=0.1)
    assert not np.isfinite(hyper.lengthscales[2])  # never turned: no lengthscale
    relevance = residual.relevance(hyper, q)
    assert set(np.argsort(-relevance)[:2]) == {1, 3}
    assert np.all(relevance[[0, 4, 5, 6]] < residual.RELEVANT_RANGE)


def test_the_same_inputs_give_the_same_fit_found_again_and_a_copy_of_it(learnt, monkeypatch):
    """A second fit of the same rows is the first one's result, not a refit; other residuals or
    another start are fitted; what a caller does to the returned lengthscales stays its own."""
    q, y, hyper, _ = learnt
    fitted = []
    compute = residual._fitted_hyperparameters
    monkeypatch.setattr(residual, "_fitted_hyperparameters", lambda *args: fitted.append(1) or compute(*args))
    again = residual.fit_hyperparameters(q, y)
    assert not fitted and again.lengthscales is not hyper.lengthscales
    np.testing.assert_array_equal(again.lengthscales, hyper.lengthscales)
    assert (again.signal_std, again.noise_std, again.at_bounds) == (hyper.signal_std, hyper.noise_std, hyper.at_bounds)
    again.lengthscales[0] = 99.0
    np.testing.assert_array_equal(residual.fit_hyperparameters(q, y).lengthscales, hyper.lengthscales)
    other = residual.fit_hyperparameters(q[:300], y[:300] * 1.5, subset=200)
    from_start = residual.fit_hyperparameters(q[:300], y[:300] * 1.5, subset=200, start=other)
    assert len(fitted) == 2 and from_start.noise_std == pytest.approx(other.noise_std, rel=1e-3)


def test_hyperparameters_left_on_a_bound_are_named(learnt):
    """A search's parameters within 1e-3 (in log) of a bound are named with the bound; the fit of a
    residual of joints 2 and 4 leaves neither of their lengthscales nor its signal or noise on a
    bound (a joint it does not depend on may run to the upper one), and the names survive the
    report's round trip."""
    bounds = [(0.0, 1.0), (0.0, 1.0), (0.0, 1.0)]
    named = kernels.at_bounds([0.0005, 0.5, 0.9995], bounds, ["a", "b", "c"])
    assert named == ("a at its lower bound", "c at its upper bound")
    _, _, hyper, _ = learnt
    assert not any(n.startswith(("signal_std", "noise_std", "q2 ", "q4 ")) for n in hyper.at_bounds)
    assert all(n.endswith("lengthscale at its upper bound") for n in hyper.at_bounds)
    bounded = Hyperparameters(hyper.lengthscales, hyper.signal_std, hyper.noise_std, ("signal_std at its lower bound",))
    assert Hyperparameters.from_report(bounded.report()).at_bounds == bounded.at_bounds
    assert "at_bounds" not in Hyperparameters(hyper.lengthscales, 1.0, 1.0).report()  # none: reports as before


def test_the_mean_predicts_new_configurations_to_within_the_noise(learnt):
    _, _, _, gp = learnt
    q = readings(np.random.default_rng(6), 500)
    error = gp.mean(q) - smooth_residual(q)
    assert np.sqrt(np.mean(error**2)) < 0.5 * NOISE
    # the predictive std is honest: most errors within 1.96 std, and the errors in units of the
    # std have an RMS near 1 (a std twice too wide gives 0.4 and fails, as does one too narrow)
    standardised = error / np.sqrt(gp.variance(q))[:, None]
    assert np.mean(np.abs(standardised) <= 1.96) > 0.85
    assert 0.6 < np.sqrt(np.mean(standardised**2)) < 1.4


def test_far_from_the_data_it_returns_to_zero_with_its_prior_uncertainty():
    rng = np.random.default_rng(7)
    q = readings(rng, 400, -0.3, 0.3)
    y = smooth_residual(q) + rng.normal(0.0, NOISE, (len(q), 3))
    hyper = Hyperparameters(np.array([0.2, 0.2, np.inf, 0.2, 0.2, 0.2, 0.2]), 2e-4, NOISE)
    gp = residual.ResidualGP(q, y, hyper)
    far = readings(rng, 50, 2.0, 2.5)
    np.testing.assert_allclose(gp.mean(far), 0.0, atol=1e-12)
    np.testing.assert_allclose(gp.variance(far), hyper.signal_std**2, rtol=1e-9)
    near = q[:50]
    assert np.all(gp.variance(near) < 0.1 * hyper.signal_std**2)


def test_with_every_row_inducing_it_is_the_exact_gp():
    rng = np.random.default_rng(8)
    q = readings(rng, 120)
    y = smooth_residual(q) + rng.normal(0.0, NOISE, (len(q), 3))
    hyper = Hyperparameters(np.array([1.0, 0.6, np.inf, 0.8, 2.0, 2.0, 2.0]), 1.5e-4, NOISE)
    gp = residual.ResidualGP(q, y, hyper, inducing=len(q))
    cov = kernel(q, q, hyper) + NOISE**2 * np.eye(len(q))
    new = readings(rng, 30)
    k_new = kernel(new, q, hyper)
    np.testing.assert_allclose(gp.mean(new), k_new @ np.linalg.solve(cov, y), rtol=1e-5, atol=1e-10)
    exact_var = hyper.signal_std**2 - np.sum(k_new * np.linalg.solve(cov, k_new.T).T, axis=1)
    np.testing.assert_allclose(gp.variance(new), exact_var, rtol=1e-4, atol=1e-14)
    _, log_det = np.linalg.slogdet(cov)
    exact = -0.5 * (np.sum(y * np.linalg.solve(cov, y)) + 3 * log_det + y.size * np.log(2 * np.pi))
    assert gp.log_likelihood == pytest.approx(exact, rel=1e-6)


def test_titsias_is_a_lower_bound_and_exact_with_every_row_inducing():
    rng = np.random.default_rng(2)
    q = rng.uniform(-2.0, 2.0, (60, 3))
    hyper = Hyperparameters(np.array([0.4, 0.6, np.inf]), 1e-4, 3e-5)  # well conditioned K
    y = 1e-4 * np.sin(3 * q[:, [0, 1, 0]]) + rng.normal(0.0, 3e-5, (len(q), 3))
    exact = likelihood.exact_log_likelihood(q, y, hyper)
    assert residual.titsias_bound(q, y, hyper, len(q)) == pytest.approx(exact, abs=1e-3)
    for m in (5, 15, 30, 45):
        assert residual.titsias_bound(q, y, hyper, m) <= exact


def test_joint_draws_have_the_marginals_and_move_together_where_readings_are_near():
    """Draws across readings: each reading's mean and variance are `mean` and `variance` (over 4000
    draws, within their sampling error); two readings far closer than a lengthscale move together,
    two far apart do not; the exact covariance under every row inducing is reproduced."""
    rng = np.random.default_rng(8)
    q = readings(rng, 60)
    y = smooth_residual(q) + rng.normal(0.0, NOISE, (len(q), 3))
    hyper = Hyperparameters(np.array([1.0, 1.0, np.inf, 1.0, 1.0, 1.0, 1.0]), 2e-4, NOISE)
    gp = residual.ResidualGP(q, y, hyper, inducing=len(q))
    at = np.vstack([readings(rng, 3), readings(rng, 1) + 0.01])
    at[3] = at[0] + 0.01  # a reading next to the first
    draws = gp.draws(at, 4000, np.random.default_rng(9))
    assert draws.shape == (4000, 4, 3)
    np.testing.assert_allclose(draws.mean(axis=0), gp.mean(at), atol=5 * np.sqrt(gp.variance(at).max() / 4000))
    np.testing.assert_allclose(draws.var(axis=0), np.repeat(gp.variance(at)[:, None], 3, axis=1), rtol=0.1)
    # with every row inducing (DTC = the exact GP) the draws' covariance is the exact posterior's
    k_ss = kernel(at, at, hyper)
    k_sn = kernel(at, q, hyper)
    exact = k_ss - k_sn @ np.linalg.solve(kernel(q, q, hyper) + NOISE**2 * np.eye(len(q)), k_sn.T)
    centred = draws[:, :, 0] - draws[:, :, 0].mean(axis=0)
    np.testing.assert_allclose(centred.T @ centred / 4000, exact, atol=0.1 * exact.diagonal().max())
    correlation = np.corrcoef(centred.T)
    assert correlation[0, 3] > 0.9 and abs(correlation[0, 1]) < 0.3


def test_a_prior_field_has_the_kernels_covariance_and_its_p95_over_readings_is_one_arms():
    """`field_draws` (a field the model lacks, as a loop that does not close declares it, through
    `model_error_draws`, which draws it independently per reading without a kernel): over 4000
    draws each reading's covariance with the others is the kernel's on each axis, readings repeated
    included (an indefinite factor falls back to the nearest PSD one); a field smooth over the
    readings gives each draw one p95 over them, spread from draw to draw as a single value's
    |N(0, s^2 I3)| is, where independent draws at each reading give nearly the same p95 every time."""
    rng = np.random.default_rng(4)
    q = readings(rng, 30)
    q[5] = q[4]  # a configuration measured twice
    signal = 1e-4
    hyper = Hyperparameters(np.array([0.8, 0.8, np.inf, 0.8, 0.8, 0.8, 0.8]), signal, 0.0)
    draws = residual.field_draws(q, hyper, 4000, np.random.default_rng(5))
    assert draws.shape == (4000, 30, 3)
    np.testing.assert_allclose(draws[:, 4], draws[:, 5], atol=1e-3 * signal)
    for axis in range(3):
        covariance = draws[:, :, axis].T @ draws[:, :, axis] / 4000
        np.testing.assert_allclose(covariance, kernel(q, q, hyper), atol=0.1 * signal**2)
    smooth = dataclasses.replace(hyper, lengthscales=np.where(hyper.turned, 1e3, np.inf))
    many = readings(rng, 300)
    field_p95 = np.quantile(
        np.linalg.norm(residual.model_error_draws(signal, smooth, many, 2000, rng), axis=-1), 0.95, axis=1
    )
    white = residual.model_error_draws(signal, None, many, 2000, rng)  # the same error without a field
    assert white.shape == (2000, 300, 3) and white.std() == pytest.approx(signal, rel=0.01)
    white_p95 = np.quantile(np.linalg.norm(white, axis=-1), 0.95, axis=1)
    chi = stats.chi(3)
    assert np.quantile(field_p95, 0.95) == pytest.approx(signal * chi.ppf(0.95), rel=0.05)
    assert np.std(field_p95) > 3 * np.std(white_p95)


def test_a_reading_one_turn_away_is_the_same_configuration_and_the_kernel_stays_positive_definite():
    """The kernel is periodic in each joint: the mean, variance and draws at q + 2 pi k (any
    joints, any turns) are those at q, while a quarter turn is a different configuration. Readings
    straddling +-pi and readings a turn apart (as a UR's campaigns read them) keep the covariance
    positive semi-definite: a periodic kernel, not a squared exponential of wrapped differences."""
    rng = np.random.default_rng(11)
    q = readings(rng, 200, -np.pi, np.pi)
    y = smooth_residual(q) + rng.normal(0.0, NOISE, (len(q), 3))
    hyper = Hyperparameters(np.array([0.8, 0.5, np.inf, 0.7, 1.0, 1.0, 1.0]), 2e-4, NOISE)
    gp = residual.ResidualGP(q, y, hyper)
    at = readings(rng, 40, -np.pi, np.pi)
    turns = rng.integers(-2, 3, at.shape) * 2 * np.pi
    scale = np.sqrt(gp.variance(at).max())
    np.testing.assert_allclose(gp.mean(at + turns), gp.mean(at), rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(gp.variance(at + turns), gp.variance(at), rtol=1e-9)
    draws = [gp.draws(x, 5, np.random.default_rng(3)) for x in (at, at + turns)]
    np.testing.assert_allclose(draws[1], draws[0], rtol=0, atol=1e-8 * scale)
    quarter = at + [0, np.pi / 2, 0, 0, 0, 0, 0]  # a quarter turn of joint 2 flips sin(2 q2)
    assert np.abs(gp.mean(quarter) - gp.mean(at)).max() > 10 * NOISE
    straddling = np.concatenate([at, at + turns, np.full((5, 7), np.pi - 1e-3), np.full((5, 7), -np.pi + 1e-3)])
    values = np.linalg.eigvalsh(kernel(straddling, straddling, hyper))
    assert values.min() > -1e-12 * values.max()


def dense_grid(rng):
    """40 positions of joints 1-2, 0.3 rad apart, each with 12 settings of joint 3, measured position
    by position: the shape of a real dense grid, small."""
    where = np.array(np.meshgrid(np.linspace(0.0, 2.1, 8), np.linspace(0.0, 1.2, 5), indexing="ij")).reshape(2, -1).T
    q = np.array([[*p, w] for p in where for w in np.linspace(-0.5, 0.5, 12)])
    return q + rng.normal(0.0, 1e-3, q.shape)


def test_on_a_dense_grid_of_short_lengthscales_enough_inducing_inputs_are_taken():
    """The residual GP at size failed because a fixed count of inducing inputs, evenly spaced over a
    grid measured position by position, misses positions whose residual varies on a shorter scale
    than their spacing: there Titsias' bound pays for the unexplained variance on every row and falls
    below independent noise, though the GP explains most of the residual. `inducing_count` adds
    inducing inputs until at most UNEXPLAINED of the prior variance is left: the bound then rises
    above independent noise and near the exact likelihood, and the mean near the exact GP's."""
    rng = np.random.default_rng(7)
    q = dense_grid(rng)
    hyper = Hyperparameters(np.array([0.1, 0.1, 2.0]), 1e-4, 2e-5)
    y = np.linalg.cholesky(kernels.covariance_with_noise(q, hyper)) @ rng.standard_normal((len(q), 3))
    exact = likelihood.exact_log_likelihood(q, y, hyper)
    iid = likelihood.iid_log_likelihood(y)
    few = 20  # half the positions
    assert residual.unexplained_share(q, hyper, few) > 0.3
    assert residual.titsias_bound(q, y, hyper, few) < iid < exact  # the GP would not be added
    m = residual.inducing_count(q, hyper, at_least=few)
    assert few < m < len(q)
    assert residual.unexplained_share(q, hyper, m) <= residual.UNEXPLAINED
    bound = residual.titsias_bound(q, y, hyper, m)
    assert iid < bound <= exact
    assert exact - bound < 0.1 * (exact - iid)
    exact_mean = kernel(q, q, hyper) @ np.linalg.solve(kernels.covariance_with_noise(q, hyper), y)
    for count, within in ((few, False), (m, True)):
        error = np.sqrt(np.mean((residual.ResidualGP(q, y, hyper, count).mean(q) - exact_mean) ** 2))
        assert bool(error < 0.2 * hyper.signal_std) is within


def test_a_smooth_residual_keeps_the_fewest_inducing_inputs_and_the_count_stops_at_its_cap():
    rng = np.random.default_rng(8)
    q = dense_grid(rng)
    assert residual.inducing_count(q, Hyperparameters(np.array([2.0, 2.0, 2.0]), 1e-4, 2e-5), at_least=20) == 20
    short = Hyperparameters(np.array([0.01, 0.01, 0.01]), 1e-4, 2e-5)
    assert residual.inducing_count(q, short, at_least=20, at_most=100) == 100
    assert residual.inducing_count(q, short, at_least=20) == len(q)  # every row: the exact GP


def test_a_matrix_applied_to_each_draw_is_the_product_draw_by_draw():
    """The draws' one matrix product (`residual._applied_to_draws`) is matrix @ z[k] for every draw
    k, each axis apart: the same numbers as the product taken draw by draw, to rounding."""
    from remaster.inference.gp import residual

    rng = np.random.default_rng(2)
    matrix, z = rng.normal(size=(7, 5)), rng.normal(size=(4, 5, 3))
    expected = np.stack([matrix @ z[k] for k in range(len(z))])
    np.testing.assert_allclose(residual._applied_to_draws(matrix, z), expected, rtol=1e-13, atol=1e-13)
