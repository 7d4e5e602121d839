"""A full-pose probe's orientations in the fit: the compiled residuals against the NumPy reference,
and, on campaigns the simulator measured (its own forward kinematics and noise rotations), the
zero-offset that a point on the last joint's axis cannot see, determined with a posterior that
covers the truth over seeds."""

import copy
import dataclasses

import numpy as np
import pytest

from remaster import spatial
from remaster.campaigns import arm_kinds
from remaster.inference import fit
from remaster.inference.blocks import paper_model
from remaster.inference.laplace_report import laplace_fit
from remaster.inference.model import correction_transforms
from remaster.inference.readings import Readings
from remaster.robot.kinematics import ForwardKinematics, flange_rotations

from ..conftest import REPO

SENSOR = "laser_tracker"


def full_pose_scenario(seed: int, orientation_noise: float = 1.7e-4, configurations=(40, 20)) -> dict:
    """An iiwa whose probe sits on the flange axis (100 mm out), every joint turned at random; the
    truth is zero-offsets only, so that a 95 % interval must cover it 95 % of the time."""
    return {
        "name": "full-pose",
        "date": "2019-03-14",
        "seed": seed,
        "robot": {"urdf": "data/robots/kuka_iiwa14.urdf", "base": "iiwa_link_0", "flange": "iiwa_link_ee"},
        "plan": {
            "design": "random_joints",
            "seconds_per_configuration": 40,
            "sets": {
                "optimization": {"configurations": configurations[0]},
                "validation": {"configurations": configurations[1]},
            },
        },
        "truth": {"zero_offsets_deg": [0.477, -0.192, 0.139, 0.099, 0.392, -0.114, 0.936]},
        "sensors": {
            SENSOR: {
                "kind": "laser_tracker",
                "marker": [0.0, 0.0, 0.1],
                "noise": 1.0e-5,
                "orientation_noise": orientation_noise,
                "probe_rotation": [0.0, 0.3, 0.0],
                "position": [1.6, 0.5, 1.0],
                "look_at": [0.0, 0.0, 0.6],
            }
        },
    }


def points_alone(sensor):
    return dataclasses.replace(
        sensor,
        table=sensor.table.drop(columns=["rx", "ry", "rz"]),
        orientation_noise=None,
        probe_rotation=None,
    )


def laplace_of(chain, sensor):
    """The zero-offset fit as the prepare stage makes it: the orientations balanced against the points."""
    registration = fit.register(chain, sensor)
    model, analysis, _ = fit.build_model(chain, sensor, registration.t_nr)
    model = fit.balanced_orientation(model)
    return model, analysis, laplace_fit(model)


def test_flange_rotations_are_the_forward_kinematics_rotations(iiwa, rng):
    q = rng.uniform(iiwa.lower, iiwa.upper, (30, 7))
    np.testing.assert_allclose(
        flange_rotations(iiwa, q), ForwardKinematics(iiwa, q).flange_poses()[:, :3, :3], atol=1e-14
    )


def test_compiled_orientation_residuals_match_the_numpy_reference(iiwa, rng):
    n = 25
    q = rng.uniform(iiwa.lower, iiwa.upper, (n, 7))
    probe = spatial.rotation_vector_to_matrix(np.array([0.1, -0.4, 0.2]))
    measured = spatial.rotation_vector_to_matrix(rng.uniform(-2.0, 2.0, (n, 3)))
    measured[3] = np.nan  # an orientation not measured: left out
    data = Readings(np.arange(n), q, rng.normal(size=(n, 3)), orientations=measured, probe_rotation=probe)
    model = paper_model(iiwa, q, data.measured, np.zeros(3), np.eye(4)).on(data)
    theta = rng.normal(0.0, 0.01, (4, len(model.names)))
    every = model.full(theta)
    flange = flange_rotations(iiwa, q[None] + every[:, None, 6:])
    predicted = correction_transforms(every[:, :6])[:, None, :3, :3] @ flange @ probe
    expected = spatial.matrix_to_rotation_vector(measured @ np.swapaxes(predicted, -1, -2))
    seen = np.arange(n) != 3
    np.testing.assert_allclose(model.orientation_residuals(theta), expected[:, seen], atol=1e-12)
    assert model.n_rows == 2 * n - 1 and model.weighted_residuals(theta).shape == (4, 2 * n - 1, 3)


def test_orientation_determines_the_zero_offset_a_point_on_the_axis_cannot_see():
    chain, sensor = arm_kinds.simulated_sensor(full_pose_scenario(seed=3, configurations=(60, 10)), SENSOR, REPO)
    _, points_analysis, _ = laplace_of(chain, points_alone(sensor))
    model, analysis, result = laplace_of(chain, sensor)
    assert "zero_offsets.q7" in points_analysis.held
    assert "zero_offsets.q7" not in analysis.held and model.n_orientations == 60
    q7 = result.names.index("zero_offsets.q7")
    assert abs(np.degrees(result.theta_map[q7]) - 0.936) < 4 * np.degrees(result.std[q7])


@pytest.mark.slow
def test_zero_offsets_with_orientation_cover_the_truth_over_seeds():
    """z = (estimate - truth) / std of every free zero-offset over 12 simulated campaigns: its mean
    square is 1 when the weighting by the stated noises is right (a chi-square with 72 degrees of
    freedom over 72 stays within 0.55-1.55 at 99.9 %)."""
    squares = []
    truth = np.radians(full_pose_scenario(0)["truth"]["zero_offsets_deg"])
    spec = full_pose_scenario(0)
    for seed in range(12):
        chain, sensor = arm_kinds.simulated_sensor(copy.deepcopy({**spec, "seed": 100 + seed}), SENSOR, REPO)
        _, _, result = laplace_of(chain, sensor)
        for name, value, std in zip(result.names, result.theta_map, result.std):
            if name.startswith("zero_offsets."):
                squares.append(((value - truth[int(name[-1]) - 1]) / std) ** 2)
    assert len(squares) == 72
    assert 0.55 < np.mean(squares) < 1.55


def test_where_the_model_lacks_an_effect_of_the_positions_the_balance_keeps_their_sigma():
    """The simulator's joint compliance (0.1 mm at the marker), which the zero-offset model lacks:
    weighed by the stated noises, the orientations' small residuals pull the one sigma a quarter
    below the points' own (and every std with it); balanced by the fit's own residuals it is the
    points' sigma within 5 %."""
    spec = full_pose_scenario(seed=5, configurations=(100, 10))
    spec["truth"].update(
        joint_compliance=[0.0, 0.8e-5, 0.0, 1.0e-5, 0.0, 1.7e-5, 0.0], payload={"mass": 1.2, "com": [0.0, 0.0, 0.02]}
    )
    chain, sensor = arm_kinds.simulated_sensor(spec, SENSOR, REPO)
    registration = fit.register(chain, sensor)
    stated, _, _ = fit.build_model(chain, sensor, registration.t_nr)
    points, _, _ = fit.build_model(chain, points_alone(sensor), registration.t_nr)
    sigma = {
        "stated": laplace_fit(stated).sigma_map,
        "balanced": laplace_fit(fit.balanced_orientation(stated)).sigma_map,
        "points": laplace_fit(points).sigma_map,
    }
    assert sigma["stated"] < 0.8 * sigma["points"]
    assert sigma["balanced"] == pytest.approx(sigma["points"], rel=0.05)


def test_orientation_columns_without_an_orientation_on_the_fitted_rows_fit_the_points_alone():
    """A probe that measured no orientation on the optimization rows: the fit is the points' alone
    (no orientation rows, joint 7 held), not a fit with a weight of nothing."""
    chain, sensor = arm_kinds.simulated_sensor(full_pose_scenario(seed=4, configurations=(30, 10)), SENSOR, REPO)
    table = sensor.table.copy()
    table.loc[table["set"] == "optimization", ["rx", "ry", "rz"]] = np.nan
    sensor = dataclasses.replace(sensor, table=table)
    model, analysis, _ = laplace_of(chain, sensor)
    assert not model.has_orientation and model.n_rows == model.n_points == 30
    assert "zero_offsets.q7" in analysis.held


def test_a_full_pose_probes_walk_is_compiled_and_the_python_walk_to_the_bit():
    """The paper's model of a full-pose probe sums its orientations' squares compiled too
    (`_kernels.orientation_sum_squares`): the weighted residuals' sum of squares to rounding, and
    the paper's random walk the same chain as the Python loop over its log_prob, bit for bit."""
    from remaster.inference.posterior_targets import PosteriorTarget
    from remaster.inference.sampling.metropolis import metropolis_paper
    from remaster.inference.sampling.target import CallableTarget

    chain, sensor = arm_kinds.simulated_sensor(full_pose_scenario(seed=5), SENSOR, REPO)
    model, _, laplace = laplace_of(chain, sensor)
    assert model.has_orientation and model.compiled_posterior
    many = laplace.theta_map + np.random.default_rng(1).normal(0.0, 1e-4, (5, len(model.names)))
    np.testing.assert_allclose(
        model.sum_squares(many), np.sum(model.weighted_residuals(many) ** 2, axis=(1, 2)), rtol=1e-10
    )
    compiled = PosteriorTarget(model)
    python = CallableTarget(compiled.names, compiled.scale, compiled.log_prob_many, compiled.log_prob)
    start = np.append(np.zeros(len(model.names)), 1e-3)
    runs = [
        metropolis_paper(t, np.random.default_rng(3), start, n_samples=6000, burn_in=4000, trace_every=7)
        for t in (compiled, python)
    ]
    assert np.array_equal(runs[0].samples, runs[1].samples) and np.array_equal(runs[0].log_prob, runs[1].log_prob)
    assert 0 < runs[0].acceptance_rate < 1
