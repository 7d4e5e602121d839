"""The closure test's held-out floor (`remaster.loop.noise_floor`, `evidence.CrossValidation.noise_inflation`):
a correct model's cross-validated residual exceeds the noise by what its Jacobian says, so that a
correct model is found closed at the test's level and is not charged a model error it does not have."""

from dataclasses import replace

import numpy as np
import pytest

from remaster.campaigns import arm_kinds
from remaster.inference import blocks, evidence, fit
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
    data = blocks.readings(chain, sensor, "optimization")
    poses = sensor.table.loc[data.rows, "pose"].to_numpy()
    folds = evidence.pose_folds(poses, 5)
    model = blocks.BlockModel(chain, data, sensor.marker, registration.t_nr, (), analysis.held)
    mode = evidence.posterior_mode(model)
    assert mode.sigma < 1e-9  # the model is exact: what it leaves is the 1e-12 m draw
    return chain, data, sensor.marker, registration.t_nr, analysis.held, folds, mode


def _noisy_fits(correct_model, seeds):
    chain, data, marker, t_nr, held, folds, mode = correct_model
    truth = data.measured
    rng = np.random.default_rng(12)
    for _ in range(seeds):
        noisy = replace(data, measured=truth + rng.normal(0.0, NOISE, truth.shape))
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


def test_a_correct_model_is_closed_at_the_tests_level_and_declares_no_model_error(correct_model):
    """The verdict against the held-out floor finds the exact model closed in at least 95 % of
    the draws; against the plain floor most draws were called not closed."""
    fits = list(_noisy_fits(correct_model, SEEDS))
    rms = [cv.rmse / np.sqrt(3.0) for cv in fits]
    held_out = [noise_floor.verdict(r, NOISE, inflation=cv.noise_inflation)["closed"] for r, cv in zip(rms, fits)]
    plain = [noise_floor.verdict(r, NOISE)["closed"] for r in rms]
    assert np.mean(held_out) >= 0.95
    assert np.mean(plain) < np.mean(held_out)


def test_the_held_out_floor_enters_the_verdict_and_the_share():
    """A residual of 1.5 x the floor is closed where a correct model's held-out mean square is
    twice the noise's (1.5 <= 1.2 sqrt 2), and its structured part is taken above sqrt 2 x the floor."""
    closed = noise_floor.verdict(1.5e-5, 1e-5, inflation=2.0)
    assert closed["closed"] is True and closed["held_out_floor_mm"] == pytest.approx(np.sqrt(2) * 1e-2)
    open_ = noise_floor.verdict(5e-5, 1e-5, inflation=2.0)
    assert open_["structured_mm"] == pytest.approx(np.sqrt(25 - 2) * 1e-2)
    assert noise_floor.share(5e-5, 4e-5, 1e-5, inflation=2.0) == pytest.approx(9 / 23)
    assert noise_floor.verdict(1.5e-5, 1e-5, inflation=0.5)["closed"] is False  # never below the floor
