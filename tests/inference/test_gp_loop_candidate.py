"""The residual GP as the loop's candidate (`remaster.inference.gp.loop_candidate`): independent noise
is not a residual to model, the GP written with the loop's results is the GP it fitted, the closure
test, and the loop on a robot whose effect is in no candidate's family (a transmission's cyclic
error)."""

import numpy as np
import pytest
from scipy import stats

from remaster import files
from remaster.campaigns import scenario
from remaster.campaigns.campaign import sensor_data
from remaster.inference import evidence, fit
from remaster.inference.gp import loop_candidate
from remaster.inference.parameter_blocks import EXTENSIONS
from remaster.loop import closure_test, loop_closure, noise_floor

from ..conftest import REPO, loop_settings
from .test_gp_residual import NOISE, readings, smooth_residual

# these run the loop closure on simulated campaigns (`-m 'not slow'` leaves them out)
pytestmark = pytest.mark.slow


def test_independent_noise_is_not_a_residual_to_model():
    rng = np.random.default_rng(10)
    q = readings(rng, 400)
    y = rng.normal(0.0, NOISE, (len(q), 3))
    folds = np.arange(len(q)) % 5
    candidate = loop_candidate.fit_and_score(q, y, y, folds)
    assert candidate.log_evidence_gain < 0.0
    squares = np.sum(y**2, axis=1)
    current = evidence.CrossValidation(np.array([squares[folds == k].mean() for k in range(5)]), candidate.points)
    gain = evidence.cv_gain(current, evidence.CrossValidation(candidate.mse, candidate.points))
    assert gain["cv_mse_fall_in_se"] < 2.0  # the loop's rule: not added
    assert abs(gain["cv_gain"]) < 0.03


# --------------------------------------------------------------------------- the closure test


def test_repeatability_is_the_pooled_spread_of_repeated_configurations():
    rng = np.random.default_rng(11)
    q = np.repeat(readings(rng, 200), 3, axis=0)
    measured = np.repeat(rng.normal(0, 0.1, (200, 3)), 3, axis=0) + rng.normal(0.0, 3e-5, (600, 3))
    spread, repeated = noise_floor.repeatability(
        np.vstack([q, readings(rng, 10)]), np.vstack([measured, np.zeros((10, 3))])
    )
    assert repeated == 200
    assert spread == pytest.approx(3e-5, rel=0.05)
    assert noise_floor.repeatability(readings(rng, 10), np.zeros((10, 3))) == (None, 0)


def test_the_verdict_and_the_shares():
    closed = noise_floor.verdict(1.1e-5, 1e-5, 0.01, 75)
    assert closed["closed"] is True and closed["p_value"] == pytest.approx(stats.chi2.sf(75 * 1.21, 75))
    open_ = noise_floor.verdict(5e-5, 1e-5, 0.01, 75)
    assert open_["closed"] is False and open_["structured_mm"] == pytest.approx(np.sqrt(24) * 1e-2)
    assert "not closed" in open_["text"]
    assert noise_floor.verdict(5e-5, None, 0.01, 75)["closed"] is None
    assert noise_floor.noise_floor(1e-5, 3e-5) == 3e-5 and noise_floor.noise_floor(None, None) is None
    # from 5 to 4 (x 1e-5) over a floor of 1: (25 - 16) / (25 - 1)
    assert noise_floor.share(5e-5, 4e-5, open_) == pytest.approx(9 / 24)
    assert noise_floor.share(1.1e-5, 0.9e-5, closed) is None  # already closed: nothing structured to share


# --------------------------------------------------------------------------- an effect outside the candidates

CYCLIC = {
    "amplitude_deg": [0, 0.02, 0, 0.015, 0, 0, 0],
    "cycles_per_turn": [1, 2, 1, 3, 1, 1, 1],
    "phase_deg": [0, 30, 0, -60, 0, 0, 0],
}


@pytest.fixture(scope="module")
def cyclic(iiwa):
    """The laser tracker of kuka-compliance's scenario, a robot with a cyclic error of joints 2 and 4."""
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-compliance.yaml")
    spec["plan"]["sets"] = {
        "optimization": {"poses": 150, "configurations": 1200},
        "validation": {"poses": 10, "configurations": 50},
    }
    spec["truth"] = {"zero_offsets_deg": [0.35, -0.21, 0.12, 0.18, -0.27, 0.09, 0.62], "cyclic_error": CYCLIC}
    out = scenario.simulate(spec, iiwa)
    meta = out.metadata["sensors"]["laser_tracker"]
    assert out.truth["effects"] == {
        "cyclic_error": {
            **CYCLIC,
            "amplitude_deg": pytest.approx(CYCLIC["amplitude_deg"]),
            "phase_deg": pytest.approx(CYCLIC["phase_deg"]),
        }
    }
    sensor = sensor_data(
        "laser_tracker",
        {**meta, "marker": np.array(meta["marker"])},
        out.tables["laser_tracker"],
        iiwa.n_joints,
        "simulated.parquet",
    )
    registration = fit.register(iiwa, sensor)
    _, analysis, _ = fit.build_model(iiwa, sensor, registration.t_nr)
    return sensor, registration.t_nr, analysis.held


# the GP's case is an effect outside every candidate: joint_harmonics (the joints' cyclic errors as
# harmonics, tests/loop/test_joint_harmonics.py) is not offered here
OUTSIDE = tuple(c for c in EXTENSIONS if c != "joint_harmonics")


def run(iiwa, cyclic, **changes):
    sensor, t_nr, held = cyclic
    return loop_closure.close_loop(
        iiwa, sensor, t_nr, held, np.random.default_rng(0), loop_settings(mcmc=None, candidates=OUTSIDE, **changes)
    ).report


def test_an_effect_outside_the_candidates_is_explained_by_the_gp_and_traced_to_its_joints(iiwa, cyclic):
    report = run(iiwa, cyclic)
    assert report.effects_added[-1] == "residual_gp"
    gp = report.residual_gp
    assert gp["added"] and gp["structure_found"]
    assert set(gp["depends_on"][:2]) == {"q2", "q4"}
    # what is left is the sensor's noise, by the GP's own account, and close to it held out
    assert gp["hyperparameters"]["noise_std_m"] == pytest.approx(cyclic[0].noise, rel=0.2)
    assert report.closure["rounds"][-1]["ratio_to_floor"] < 1.5
    assert report.validation_rmse_after_mm < 0.4 * report.validation_rmse_before_mm
    # a parametric effect added on the way explains a small share and is not named as the cause
    assert report.closure["main_causes"] == ["residual_gp"]
    for name, value in report.closure["share_of_structured_residual"].items():
        assert (value is not None and value >= noise_floor.MAIN_CAUSE_SHARE) == (name == "residual_gp")


def test_without_the_gp_the_loop_says_it_is_not_closed_and_where_the_residual_lives(iiwa, cyclic):
    report = run(iiwa, cyclic, residual_gp=None)
    assert "residual_gp" not in report.effects_added
    assert report.closure["closed"] is False
    assert report.closure["main_causes"] == []
    assert any(w.startswith("loop not closed") and "not its cause" in w for w in report.warnings)
    # what its declared model error does not hold, and that its zero-offsets' U carries the field's share
    (closure,) = [w for w in report.warnings if w.startswith("loop not closed")]
    assert closure.endswith(closure_test.SHAPE_OF_THE_DECLARED_ERROR)
    assert report.model_error_share["computed"] and report.model_error_share["parameters"]
    assert any(w.startswith("no candidate effect explains what is left") for w in report.warnings)


def test_the_gp_written_with_the_loop_results_is_the_gp_the_loop_fitted():
    rng = np.random.default_rng(12)
    q = readings(rng, 300)
    y = smooth_residual(q) + rng.normal(0.0, NOISE, (len(q), 3))
    candidate = loop_candidate.fit_and_score(q, y, y, np.arange(len(q)) % 5, subset=200, inducing=100)
    section = {"added": True, "hyperparameters": candidate.gp.hyper.report(), "inducing": len(candidate.gp.inducing)}
    rebuilt = loop_candidate.from_results(loop_candidate.training_frame(candidate), section)
    new = readings(rng, 40)
    np.testing.assert_allclose(rebuilt.mean(new), candidate.gp.mean(new), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(rebuilt.variance(new), candidate.gp.variance(new), rtol=1e-9, atol=1e-18)
    assert loop_candidate.from_results(loop_candidate.training_frame(candidate), {**section, "added": False}) is None
