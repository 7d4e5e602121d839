"""Properties that must hold for any input in range (hypothesis, bounded and derandomized so the
suite stays fast and reproducible): FK/IK round trips, rigid registration recovered exactly,
the accuracy metrics frame-invariant, non-negative and zero on perfect data."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from remaster import spatial
from remaster.inference import metrics
from remaster.robot import ik, kinematics, registration

SETTINGS = settings(max_examples=100, deadline=None, derandomize=True)

angles = st.floats(-np.pi, np.pi, allow_nan=False)
rigid = st.tuples(angles, st.floats(-np.pi / 2, np.pi / 2), angles, *[st.floats(-5.0, 5.0, allow_nan=False)] * 3)
seeds = st.integers(0, 2**32 - 1)


def transform(params) -> np.ndarray:
    yaw, pitch, roll, x, y, z = params
    return spatial.homogeneous(spatial.euler_zyx_to_matrix(yaw, pitch, roll), np.array([x, y, z]))


def iiwa_configuration():
    """Configurations within the iiwa's limits (rad)."""
    limits = np.deg2rad([170, 120, 170, 120, 170, 120, 175])
    return st.tuples(*[st.floats(-lim, lim, allow_nan=False) for lim in limits]).map(np.array)


@pytest.fixture(scope="module")
def solver(iiwa):
    return ik.SRSInverseKinematics(iiwa)


def generic(solver, q) -> bool:
    """Away from the elbow, wrist and shoulder singularities (one solution per branch there)."""
    pose = kinematics.flange_poses(solver.chain, q[None])[0]
    wrist = (pose @ solver.home_inverse @ np.r_[solver.wrist, 1.0])[:3]
    off_axis1 = np.linalg.norm(wrist[:2] - solver.shoulder[:2])
    return abs(np.sin(q[3])) > 1e-3 and abs(np.sin(q[5])) > 1e-3 and off_axis1 > 1e-3


# --------------------------------------------------------------------------- kinematics


@SETTINGS
@given(q=iiwa_configuration())
def test_ik_of_fk_contains_the_configuration_and_every_solution_reaches_the_pose(iiwa, solver, q):
    assume(generic(solver, q))
    pose = kinematics.flange_poses(iiwa, q[None])[0]
    solutions = solver.solve(pose, q3=q[2])
    assert len(solutions) >= 1 and np.all(iiwa.within_limits(solutions))
    reached = kinematics.flange_poses(iiwa, solutions)
    assert np.abs(reached - pose).max() <= 1e-9
    assert np.abs(ik.wrap_angle(solutions - q)).max(axis=1).min() < 1e-6
    np.testing.assert_array_equal(solutions[:, 2], q[2])


@SETTINGS
@given(
    q=iiwa_configuration(),
    offsets=st.tuples(*[st.floats(-0.05, 0.05)] * 7).map(np.array),
    marker=st.tuples(*[st.floats(-0.2, 0.2)] * 3).map(np.array),
)
def test_marker_fk_is_the_flange_pose_applied_to_the_marker_and_offsets_add(iiwa, q, offsets, marker):
    fk = kinematics.ForwardKinematics(iiwa, q[None])
    with_offsets = fk.points(marker, offsets)[0]
    shifted = kinematics.ForwardKinematics(iiwa, (q + offsets)[None])
    np.testing.assert_allclose(with_offsets, shifted.points(marker)[0], atol=1e-12)
    np.testing.assert_allclose(with_offsets, spatial.transform_points(shifted.flange_poses()[0], marker), atol=1e-12)


# --------------------------------------------------------------------------- registration


@SETTINGS
@given(truth=rigid, seed=seeds, n=st.integers(3, 40))
def test_kabsch_and_three_point_recover_a_rigid_motion(truth, seed, n):
    t_nr = transform(truth)
    robot = np.random.default_rng(seed).uniform(-1.0, 1.0, (n, 3))
    triple = registration.spread_out_triple(robot)
    assume(registration.triangle_height(robot[triple]) > 0.05)  # three random points may be nearly collinear
    sensor = spatial.transform_points(t_nr, robot)
    np.testing.assert_allclose(registration.kabsch(robot, sensor), t_nr, atol=1e-9)
    np.testing.assert_allclose(registration.three_point(robot[triple], sensor[triple]), t_nr, atol=1e-9)


@SETTINGS
@given(motion=rigid, seed=seeds)
def test_kabsch_moves_with_the_sensor_and_inverts(motion, seed):
    """Noisy points: moving the sensor frame by M moves the fit to M T; swapping the frames inverts it."""
    rng = np.random.default_rng(seed)
    robot = rng.uniform(-1.0, 1.0, (30, 3))
    sensor = spatial.transform_points(transform(rng.uniform(-1, 1, 6)), robot) + rng.normal(0, 1e-3, (30, 3))
    fitted = registration.kabsch(robot, sensor)
    moved = transform(motion)
    np.testing.assert_allclose(
        registration.kabsch(robot, spatial.transform_points(moved, sensor)), moved @ fitted, atol=1e-9
    )
    np.testing.assert_allclose(registration.kabsch(sensor, robot), spatial.invert(fitted), atol=1e-9)


# --------------------------------------------------------------------------- metrics

points = hnp.arrays(
    np.float64,
    st.tuples(st.integers(2, 12), st.just(3)),
    elements=st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False),
)


@st.composite
def measured_and_modelled(draw):
    """p_ref (n, 3), p_robot (n, 3) and group labels (n,)."""
    p_ref = draw(points)
    p_robot = draw(hnp.arrays(np.float64, p_ref.shape, elements=st.floats(-2.0, 2.0, allow_nan=False)))
    groups = draw(hnp.arrays(np.int64, len(p_ref), elements=st.integers(0, 3)))
    return p_ref, p_robot, groups


def pairs_per_group(groups) -> int:
    _, counts = np.unique(groups, return_counts=True)
    return int(np.sum(counts * (counts - 1) // 2))


@SETTINGS
@given(data=measured_and_modelled(), sensor_motion=rigid, robot_motion=rigid)
def test_relative_errors_do_not_depend_on_either_frame(data, sensor_motion, robot_motion):
    p_ref, p_robot, groups = data
    errors = metrics.relative_errors(p_ref, p_robot, groups)
    moved = metrics.relative_errors(
        spatial.transform_points(transform(sensor_motion), p_ref),
        spatial.transform_points(transform(robot_motion), p_robot),
        groups,
    )
    np.testing.assert_allclose(moved, errors, atol=1e-12)
    assert errors.shape == (pairs_per_group(groups),) and np.all(errors >= 0)


@SETTINGS
@given(data=measured_and_modelled(), motion=rigid)
def test_relative_errors_are_zero_on_perfect_data(data, motion):
    """The sensor sees the model's points in its own frame, exactly: every d_ij is 0."""
    _, p_robot, groups = data
    p_ref = spatial.transform_points(transform(motion), p_robot)
    assert np.abs(metrics.relative_errors(p_ref, p_robot, groups)).max(initial=0.0) <= 1e-12


@SETTINGS
@given(data=measured_and_modelled(), motion=rigid)
def test_post_registration_errors_are_frame_invariant_non_negative_and_zero_on_perfect_data(data, motion):
    p_ref, p_pred, _ = data
    errors = metrics.post_registration_errors(p_ref, p_pred)
    assert errors.shape == (len(p_ref),) and np.all(errors >= 0)
    m = transform(motion)
    moved = metrics.post_registration_errors(spatial.transform_points(m, p_ref), spatial.transform_points(m, p_pred))
    np.testing.assert_allclose(moved, errors, atol=1e-12)
    assert np.all(metrics.post_registration_errors(p_pred, p_pred) == 0.0)


@SETTINGS
@given(data=measured_and_modelled(), unseen=st.data())
def test_unseen_rows_drop_out_of_the_relative_metric(data, unseen):
    """A NaN row (marker not seen) takes its pairs away and changes no other pair."""
    p_ref, p_robot, groups = data
    row = unseen.draw(st.integers(0, len(p_ref) - 1))
    with_nan = p_ref.copy()
    with_nan[row] = np.nan
    keep = np.arange(len(p_ref)) != row
    np.testing.assert_array_equal(
        metrics.relative_errors(with_nan, p_robot, groups),
        metrics.relative_errors(p_ref[keep], p_robot[keep], groups[keep]),
    )
