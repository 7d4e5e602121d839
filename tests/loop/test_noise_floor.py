"""The closure test's held-out floor (`remaster.loop.noise_floor`, `evidence.CrossValidation.noise_inflation`):
a correct model's cross-validated residual exceeds the noise by what its Jacobian says, so that a
correct model is found closed at the test's level and is not charged a model error it does not have."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from remaster.campaigns import arm_kinds
from remaster.inference import blocks, evidence, fit
from remaster.inference.readings import readings
from remaster.loop import noise_floor

from ..conftest import REPO

NOISE = 1.0e-5  # m per axis, the simulated tracker's
SEEDS = 60


@pytest.fixture(scope="module")
def correct_model():
    """A 25-configuration iiwa campaign's zero-offset model, its pose folds, and the true points:
    the simulator's (zero-offsets only, which the model holds exactly; its kinematics are not the
    fit's code), measured without noise, so that only the noise is drawn here."""
    tracker = {**arm_kinds.TRACKER, "noise": 1e-12}
    spec = arm_kinds.iiwa_scenario("held-out-floor", seed=4, sensors={"laser_tracker": tracker})
    chain, sensor = arm_kinds.simulated_sensor(spec, "laser_tracker", REPO)
    registration = fit.register(chain, sensor)
    _, analysis, _ = fit.build_model(chain, sensor, registration.t_nr)
    data = readings(chain, sensor, "optimization")
    poses = sensor.table.loc[data.rows, "pose"].to_numpy()
    folds = evidence.pose_folds(poses, 5)
    model = blocks.BlockModel(chain, data, sensor.marker, registration.t_nr, (), analysis.held)
    mode = evidence.posterior_mode(model)
    assert mode.sigma < 1e-9  # the model is exact: what it leaves is the 1e-12 m draw
    return chain, data, sensor.marker, registration.t_nr, analysis.held, folds, mode


def _noisy_fits(correct_model, seeds, discrepancy=0.0):
    """Cross-validations of the exact model over `seeds` noise draws, each number also moved by a
    model error of std `discrepancy` (m) that no parameter follows (drawn independently, as the
    declared model error is)."""
    chain, data, marker, t_nr, held, folds, mode = correct_model
    truth = data.measured
    rng = np.random.default_rng(12)
    for _ in range(seeds):
        moved = rng.normal(0.0, discrepancy, truth.shape) if discrepancy else 0.0
        noisy = replace(data, measured=truth + moved + rng.normal(0.0, NOISE, truth.shape))
        model = blocks.BlockModel(chain, noisy, marker, t_nr, (), held)
        yield evidence.cross_validate(evidence.posterior_mode(model, mode.theta), folds)


def test_the_held_out_inflation_is_what_a_correct_model_shows_over_noise_draws(correct_model):
    """Over 60 noise draws the pooled held-out mean square of the exact model, over 3 NOISE^2, has
    the mean the Jacobian predicts (within 4 standard errors), and it is far from 1: the plain
    noise floor would call this exact model not closed."""
    fits = list(_noisy_fits(correct_model, SEEDS))
    observed = np.array([cv.rmse**2 / (3.0 * NOISE**2) for cv in fits])
    predicted = np.array([cv.noise_inflation for cv in fits])
    standard_error = observed.std(ddof=1) / np.sqrt(SEEDS)
    assert abs(observed.mean() - predicted.mean()) < 4.0 * standard_error
    assert predicted.mean() > 1.2  # what the plain floor would have missed
    assert np.ptp(predicted) < 0.01 * predicted.mean()  # the Jacobian's, not the draw's


def test_the_structured_residual_is_what_a_fit_of_every_row_leaves(correct_model):
    """A model error of 3 x the noise per number that no parameter follows, over 60 draws on the
    25-configuration campaign: the structured residual the verdict states is that error (its mean
    square within 4 standard errors of 9 NOISE^2), not the held-out excess, which the folds'
    parameter spread inflates by the same factor as the noise (c, 1.55 here)."""
    fits = list(_noisy_fits(correct_model, SEEDS, discrepancy=3.0 * NOISE))
    tested = [
        noise_floor.verdict(cv.rmse / np.sqrt(3.0), NOISE, 0.01, cv.held_out_numbers, cv.null_cumulants) for cv in fits
    ]
    squares = np.array([(t["structured_mm"] * 1e-3) ** 2 for t in tested]) / NOISE**2
    assert all(t["closed"] is False for t in tested)
    assert abs(squares.mean() - 9.0) < 4.0 * squares.std(ddof=1) / np.sqrt(SEEDS)
    excess = np.array([(t["rms_per_axis_mm"] ** 2 - t["held_out_floor_mm"] ** 2) * 1e-6 for t in tested]) / NOISE**2
    ratio = np.mean([cv.noise_inflation for cv in fits])
    assert ratio > 1.4 and abs(excess.mean() / squares.mean() - ratio) < 0.05 * ratio  # the excess is c s^2


def test_a_correct_models_closure_p_values_are_uniform_over_noise_draws(correct_model):
    """The closure test's p-value of the exact model over 60 noise draws is uniform (its level is
    its rejection rate): the share below 0.1 within the binomial 99 % interval of 60 draws at 0.1, and
    a Kolmogorov-Smirnov test against the uniform law does not reject at 1 %."""
    fits = list(_noisy_fits(correct_model, SEEDS))
    tested = [
        noise_floor.verdict(cv.rmse / np.sqrt(3.0), NOISE, 0.1, cv.held_out_numbers, cv.null_cumulants) for cv in fits
    ]
    p_values = np.array([t["p_value"] for t in tested])
    low, high = stats.binom.ppf([0.005, 0.995], SEEDS, 0.1)
    assert low <= np.sum(p_values < 0.1) <= high
    assert stats.kstest(p_values, "uniform").pvalue > 0.01
    assert np.mean([not t["closed"] for t in tested]) == np.mean(p_values < 0.1)


def test_the_held_out_cumulants_are_those_of_the_folds_linear_map():
    """`evidence.held_out_cumulants` against the eigenvalues of the covariance of every held-out
    residual, built row by row from each fold's least-squares step (priors on two parameters, one
    weakly seen)."""
    rng = np.random.default_rng(3)
    n, p, k = 30, 6, 5
    jacobian = rng.normal(size=(n, 3, p))
    jacobian[:, :, 5] *= 0.05
    folds = np.arange(n) % k
    precision = np.r_[np.zeros(4), 10.0, 30.0]
    linear_map = np.zeros((3 * n, 3 * n))
    inverses, grams = [], []
    for fold in range(k):
        train = folds != fold
        j_train, j_fold = jacobian[train].reshape(-1, p), jacobian[~train].reshape(-1, p)
        lhs = j_train.T @ j_train + np.diag(precision)
        inverses.append(np.linalg.inv(lhs))
        grams.append(j_fold.T @ j_fold)
        held, fitted = np.flatnonzero(np.repeat(~train, 3)), np.flatnonzero(np.repeat(train, 3))
        linear_map[np.ix_(held, held)] += np.eye(len(held))
        linear_map[np.ix_(held, fitted)] -= j_fold @ np.linalg.solve(lhs, j_train.T)
    weights = np.linalg.eigvalsh(linear_map @ linear_map.T)
    expected = (weights.sum(), 2 * np.sum(weights**2), 8 * np.sum(weights**3))
    total = jacobian.reshape(-1, p).T @ jacobian.reshape(-1, p)
    assert evidence.held_out_cumulants(inverses, grams, total, 3 * n) == pytest.approx(expected, rel=1e-10)


def test_the_held_out_floor_enters_the_verdict_and_the_share():
    """Where a correct model's held-out error is twice the noise's (every weight 2), a residual of 1.5 x
    the floor is closed (75 numbers: p = 0.2), and the structured part is taken above sqrt 2 x the floor."""
    doubled = (150.0, 8.0 * 75, 64.0 * 75)
    closed = noise_floor.verdict(1.5e-5, 1e-5, 0.01, 75, doubled)
    assert closed["closed"] is True and closed["held_out_floor_mm"] == pytest.approx(np.sqrt(2) * 1e-2)
    assert closed["p_value"] == pytest.approx(stats.chi2.sf(75 * 2.25 / 2.0, 75))
    open_ = noise_floor.verdict(5e-5, 1e-5, 0.01, 75, doubled)
    # the excess over the held-out floor, (25 - 2) floor^2, is twice the structured residual's square
    assert open_["structured_mm"] == pytest.approx(np.sqrt((25 - 2) / 2) * 1e-2)
    assert noise_floor.share(5e-5, 4e-5, open_) == pytest.approx(9 / 23)
    # the same ratio over many more numbers is beyond the level
    assert noise_floor.verdict(1.05e-5, 1e-5, 0.01, 52_500)["closed"] is False
