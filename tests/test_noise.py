"""A laser tracker's range/transverse noise: the whitening is S^-1/2, the simulator draws it, and the
loop closure chooses it by evidence only when the data have it."""

import math

import numpy as np
import pytest
from scipy import stats
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from remaster import files, noise
from remaster.campaigns import folders, scenario, simulation
from remaster.inference import evidence, fit
from remaster.inference.readings import readings
from remaster.loop import selection as loop_selection

from .conftest import REPO, loop_settings


def test_whitening_turns_the_covariance_into_the_identity_and_the_log_det_is_its_determinant(rng):
    shape = noise.RangeTransverse(1.7)
    points = rng.normal(0.0, 1.5, (50, 3))
    u = points / np.linalg.norm(points, axis=1, keepdims=True)
    along = u[:, :, None] * u[:, None, :]
    k2 = 1.0 + (1.7 * np.linalg.norm(points, axis=1)) ** 2
    covariance = along + k2[:, None, None] * (np.eye(3) - along)
    w = shape.whitening(points)
    np.testing.assert_allclose(w @ covariance @ np.swapaxes(w, 1, 2), np.broadcast_to(np.eye(3), w.shape), atol=1e-12)
    assert shape.log_det_term(points) == pytest.approx(-0.5 * np.sum(np.linalg.slogdet(covariance)[1]), rel=1e-12)
    np.testing.assert_allclose(noise.RangeTransverse(0.0).whitening(points), np.broadcast_to(np.eye(3), w.shape))


def tracker_campaign(tmp_path, iiwa, growth: float):
    """kuka-twin's laser tracker alone, zero-offsets only in the truth (so the base model leaves
    only noise), with range noise 10 um and transverse growth `growth` per metre."""
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-twin.yaml")
    spec["name"] = "tracker"
    for effect in ("joint_compliance", "link_errors", "payload", "drift_deg_per_hour"):
        spec["truth"].pop(effect, None)
    del spec["sensors"]["motion_capture"]
    spec["plan"]["reference_sensor"] = "laser_tracker"
    spec["sensors"]["laser_tracker"].pop("marker_error", None)
    spec["sensors"]["laser_tracker"].update(transverse_growth_per_m=growth, missing=0)
    out = scenario.simulate(spec, iiwa)
    folder = folders.write_campaign(tmp_path / "tracker", out.metadata, out.tables)
    return folders.read_campaign(folder, repo_root=REPO), out


def test_the_simulator_draws_range_and_transverse_noise_of_the_stated_size(tmp_path, iiwa):
    campaign, out = tracker_campaign(tmp_path, iiwa, 2.0)
    truth = out.truth["sensors"]["laser_tracker"]
    measured = campaign.sensors["laser_tracker"].positions()
    q = campaign.sensors["laser_tracker"].q()
    true_robot = scenario.robot_from_truth(out.truth)
    sensor = scenario.sensor_from_truth(out.truth, "laser_tracker", campaign.sensors["laser_tracker"].marker)
    exact = simulation.true_sensor_positions(campaign.chain, true_robot, sensor, q, None)
    error = measured - exact
    u = exact / np.linalg.norm(exact, axis=1, keepdims=True)
    along = np.sum(error * u, axis=1)
    transverse = error - along[:, None] * u
    ratio = np.sqrt(1.0 + (2.0 * np.linalg.norm(exact, axis=1)) ** 2)
    assert truth["transverse_growth_per_m"] == 2.0
    # standardised, each is N(0, 1) per component: range one, transverse two
    assert stats.kstest(along / 1e-5, "norm").pvalue > 0.01
    assert stats.chi2(2 * len(q)).cdf(np.sum((transverse / (1e-5 * ratio[:, None])) ** 2)) == pytest.approx(
        0.5, abs=0.49
    )
    assert np.std(np.linalg.norm(transverse, axis=1)) > 2 * np.std(along)


def noise_choice(campaign, floor=math.inf):
    sensor = campaign.sensors["laser_tracker"]
    registration = fit.registration_stage(campaign, "laser_tracker")
    data = readings(campaign.chain, sensor, "optimization")
    poses = sensor.table.loc[data.rows, "pose"].to_numpy()
    return loop_selection.select(
        campaign.chain,
        data,
        sensor.marker,
        registration.t_nr,
        {"zero_offsets.q1": 0.0},
        poses,
        loop_settings(candidates=(), residual_gp=None),
        tracker=floor,
    )


@pytest.mark.parametrize("growth", [0.0, 2.0])
def test_the_loop_takes_the_range_transverse_noise_only_when_the_tracker_has_it(tmp_path, iiwa, growth):
    """Isotropic noise: the isotropic model stays (evidence gain below the threshold). Transverse
    growth of 2 per metre: chosen, g found within its stated uncertainty, sigma the range std
    (10 um) where the isotropic sigma is inflated by the transverse noise."""
    campaign, _ = tracker_campaign(tmp_path, iiwa, growth)
    selection = noise_choice(campaign)
    report = selection.noise
    if growth == 0.0:
        assert report["chosen"] == "isotropic" and report["log_evidence_gain"] < 5.0
        assert selection.final.model.noise is None
        return
    assert report["chosen"] == "range_transverse" and report["log_evidence_gain"] > 5.0
    assert abs(np.log(report["transverse_growth_per_m"] / growth)) < 3 * report["growth_std_log"]
    assert report["sigma_range_mm"] == pytest.approx(0.010, rel=0.1)
    assert report["sigma_isotropic_mm"] > 2 * report["sigma_range_mm"]
    assert selection.final.model.noise.growth_per_m == report["transverse_growth_per_m"]


def test_a_zero_growth_shape_is_the_isotropic_model(tmp_path, iiwa):
    campaign, _ = tracker_campaign(tmp_path, iiwa, 0.0)
    model = noise_choice(campaign).final.model
    iso, flat = evidence.posterior_mode(model), evidence.posterior_mode(model.with_noise(noise.RangeTransverse(0.0)))
    assert flat.log_evidence == pytest.approx(iso.log_evidence, abs=1e-9)
    np.testing.assert_allclose(flat.theta, iso.theta, rtol=0, atol=1e-15)


def test_a_frame_that_cannot_be_the_trackers_is_said_so(tmp_path, iiwa):
    """Positions already in the robot frame (the sensor's origin at the robot's base) have no
    tracker head to measure directions from; the twin's tracker stands 1.7 m away."""
    campaign, _ = tracker_campaign(tmp_path, iiwa, 0.0)
    measured = campaign.sensors["laser_tracker"].positions()
    measured = measured[np.all(np.isfinite(measured), axis=1)]
    registration = fit.registration_stage(campaign, "laser_tracker")
    assert noise.frame_problem(registration.t_nr, measured) is None
    why = noise.frame_problem(np.eye(4), measured)
    assert "robot's base origin" in why and "not in the tracker's own frame" in why


@pytest.mark.parametrize(
    "key, value, says",
    [
        ("growth_factor", 1.0, "1.0 is less than or equal to the minimum of 1"),
        ("growth_per_m", 0, "0 is less than or equal to the minimum of 0"),
        ("grwoth_per_m", 1.0, "Additional properties are not allowed ('grwoth_per_m' was unexpected)"),
    ],
)
def test_a_bad_tracker_noise_prior_is_refused_by_the_schema(key, value, says):
    config = files.read_yaml(REPO / "config.yaml")
    config["loop_closure"]["tracker_noise"][key] = value
    with pytest.raises(WorkflowError) as info:
        validate(config, str(REPO / "src" / "remaster" / "data" / "config.schema.yaml"))
    assert f"ValidationError: {says}" in str(info.value)
    assert "On instance['loop_closure']['tracker_noise']" in str(info.value)


def test_the_config_turns_the_tracker_noise_off_or_sets_its_prior():
    config = files.read_yaml(REPO / "config.yaml")

    def tracker_noise(section):  # config.yaml with this tracker_noise section, the schema filling the rest
        return loop_settings({**config, "loop_closure": {**config["loop_closure"], "tracker_noise": section}})

    assert tracker_noise({"enabled": False}).tracker_noise is None
    wide = tracker_noise({"growth_per_m": 0.5, "growth_factor": 10})
    assert wide.tracker_noise == {"growth_per_m": 0.5, "growth_factor": 10.0}


def test_a_range_std_above_the_noise_floor_is_model_error_and_not_kept(tmp_path, iiwa):
    """The tracker's transverse growth found against the floor of its stated range noise (10 um): kept.
    Against a floor a fifth of that, its range std is 4 x the floor, as where the shape takes up an effect
    the model lacks: the isotropic noise stays, and the report says why."""
    campaign, _ = tracker_campaign(tmp_path, iiwa, 2.0)
    kept = noise_choice(campaign, floor=1e-5).noise
    assert kept["chosen"] == "range_transverse" and "refused" not in kept and kept["noise_floor_mm"] == 0.01
    selection = noise_choice(campaign, floor=2e-6)
    refused = selection.noise
    assert refused["chosen"] == "isotropic" and refused["log_evidence_gain"] > 5.0
    assert selection.final.model.noise is None
    assert "range std" in refused["refused"] and "x the instrument's noise floor (0.002 mm)" in refused["refused"]
