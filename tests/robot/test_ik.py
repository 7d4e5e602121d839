"""Analytic S-R-S inverse kinematics of the iiwa: all branches, limits, out of reach, singular poses."""

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from remaster import spatial
from remaster.robot import ik, kinematics

TOLERANCE = 1e-9  # m and rotation-matrix entries
ANGLE_TOLERANCE = 1e-6  # rad, recovering the original configuration


@pytest.fixture(scope="module")
def solver(iiwa):
    return ik.SRSInverseKinematics(iiwa)


def pose_of(chain, q):
    return kinematics.flange_poses(chain, np.atleast_2d(q))[0]


def pose_errors(chain, solutions, pose):
    """Largest position (m) / rotation-entry error of each solution, (k,)."""
    poses = kinematics.flange_poses(chain, solutions)
    return np.maximum(
        np.abs(poses[:, :3, 3] - pose[:3, 3]).max(axis=1), np.abs(poses[:, :3, :3] - pose[:3, :3]).max(axis=(1, 2))
    )


def assert_valid(chain, solutions, pose):
    assert solutions.ndim == 2 and solutions.shape[1] == 7
    assert np.all(np.isfinite(solutions))
    if len(solutions):
        assert pose_errors(chain, solutions, pose).max() <= TOLERANCE


def angular_distance(a, b):
    return np.abs(ik.wrap_angle(np.asarray(a) - np.asarray(b))).max(axis=-1)


def random_configurations(chain, rng, n, q3):
    q = rng.uniform(chain.lower, chain.upper, (n, 7))
    q[:, 2] = q3
    return q


def is_generic(solver, q):
    """Away from the elbow, wrist and shoulder singularities."""
    # the wrist joints leave the wrist centre fixed, so it is T(q) M^-1 W
    wrist = (pose_of(solver.chain, q) @ solver.home_inverse @ np.r_[solver.wrist, 1.0])[:3]
    off_axis1 = np.linalg.norm(wrist[:2] - solver.shoulder[:2])
    return abs(np.sin(q[3])) > 1e-3 and abs(np.sin(q[5])) > 1e-3 and off_axis1 > 1e-3


# --------------------------------------------------------------------------- generic poses


limited_q = st.tuples(*[st.floats(-lim, lim) for lim in np.deg2rad([170, 120, 170, 120, 170, 120, 175])])


@pytest.mark.parametrize("q3", [0.0, 0.3])
@settings(max_examples=60, deadline=None)
@given(q=limited_q)
def test_fk_then_ik_recovers_configuration(iiwa, solver, q3, q):
    q = np.array(q)
    q[2] = q3
    pose = pose_of(iiwa, q)
    solutions = solver.solve(pose, q3=q3, within_limits=False)
    assert len(solutions) >= 1  # reachable by construction, singular or not
    assert_valid(iiwa, solutions, pose)
    assert np.all(solutions[:, 2] == q3)
    if is_generic(solver, q):
        assert angular_distance(solutions, q).min() < ANGLE_TOLERANCE


@pytest.mark.parametrize("q3", [0.0, 0.3, -1.5])
def test_generic_poses_have_eight_distinct_branches(iiwa, solver, rng, q3):
    for q in random_configurations(iiwa, rng, 40, q3):
        pose = pose_of(iiwa, q)
        solutions, branches = solver.solve(pose, q3=q3, within_limits=False, return_branches=True)
        assert solutions.shape == (8, 7)
        assert_valid(iiwa, solutions, pose)
        assert angular_distance(solutions, q).min() < ANGLE_TOLERANCE
        pairwise = [angular_distance(a, b) for a, b in itertools.combinations(solutions, 2)]
        assert min(pairwise) > 1e-3
        # one solution per branch, sorted +1 before -1 (shoulder, elbow, wrist)
        assert [tuple(b) for b in branches] == list(itertools.product([1, -1], repeat=3))


def test_branch_labels_follow_elbow_and_wrist_signs(iiwa, solver, rng):
    for q in random_configurations(iiwa, rng, 30, 0.0):
        if not is_generic(solver, q):
            continue
        solutions, branches = solver.solve(pose_of(iiwa, q), within_limits=False, return_branches=True)
        original = np.argmin(angular_distance(solutions, q))
        assert branches[original, 1] == np.sign(q[3])
        assert branches[original, 2] == np.sign(q[5])


def test_within_limits_filters(iiwa, solver, rng):
    filtered_any = False
    for q in random_configurations(iiwa, rng, 40, 0.0):
        pose = pose_of(iiwa, q)
        everything = solver.solve(pose, within_limits=False)
        limited = solver.solve(pose)
        assert_valid(iiwa, limited, pose)
        assert np.all(iiwa.within_limits(limited))
        np.testing.assert_array_equal(limited, everything[iiwa.within_limits(everything)])
        assert angular_distance(limited, q).min() < ANGLE_TOLERANCE
        filtered_any |= len(limited) < len(everything)
    assert filtered_any


def test_q3_outside_its_limits(iiwa, solver):
    q = np.array([0.2, 0.4, 3.0, 1.0, -0.3, 0.8, 0.1])
    pose = pose_of(iiwa, q)
    assert solver.solve(pose, q3=3.0).shape == (0, 7)
    solutions = solver.solve(pose, q3=3.0, within_limits=False)
    assert_valid(iiwa, solutions, pose)
    assert angular_distance(solutions, q).min() < ANGLE_TOLERANCE


def test_equivalents_two_pi_apart_within_wide_limits(iiwa):
    wide = dataclasses.replace(iiwa, lower=iiwa.lower.copy(), upper=iiwa.upper.copy())
    wide.lower[6], wide.upper[6] = -2 * np.pi, 2 * np.pi
    q = np.array([0.2, 0.4, 0.0, 1.0, -0.3, 0.8, 0.1])
    pose = pose_of(iiwa, q)
    narrow = ik.SRSInverseKinematics(iiwa).solve(pose)
    both = ik.SRSInverseKinematics(wide).solve(pose)
    assert len(both) == 2 * len(narrow)  # every q7 in (-pi, pi] has one more value in [-2 pi, 2 pi]
    assert_valid(iiwa, both, pose)
    assert np.all(wide.within_limits(both))


# --------------------------------------------------------------------------- out of reach


@pytest.mark.parametrize("within_limits", [True, False])
def test_out_of_reach_returns_no_solution(iiwa, solver, within_limits):
    pose = pose_of(iiwa, [0.3, 0.5, 0.0, 1.0, 0.4, 0.2, 0.9])
    for shift in ([2.0, 0.0, 0.0], [0.0, 0.0, -3.0], [50.0, 50.0, 50.0]):
        far = pose.copy()
        far[:3, 3] += shift
        assert solver.solve(far, within_limits=within_limits).shape == (0, 7)
    at_shoulder = pose.copy()  # wrist centre on the shoulder: the elbow cannot fold that far
    at_shoulder[:3, 3] += solver.shoulder - (pose @ solver.home_inverse @ np.r_[solver.wrist, 1.0])[:3]
    assert solver.solve(at_shoulder, within_limits=within_limits).shape == (0, 7)


def test_invalid_input(iiwa, solver):
    with pytest.raises(ValueError):
        solver.solve(np.eye(3))
    with pytest.raises(ValueError):
        solver.solve(np.full((4, 4), np.nan))
    assert solver.solve(np.diag([2.0, 2.0, 2.0, 1.0])).shape == (0, 7)  # not rigid: no solution


def test_rejects_chains_that_are_not_srs(iiwa, ur5_dh):
    with pytest.raises(ValueError, match="7 joints"):
        ik.SRSInverseKinematics(ur5_dh)
    transforms = iiwa.joint_transforms.copy()
    transforms[1, 0, 3] += 1e-3  # axis 2 moved 1 mm off axis 1
    with pytest.raises(ValueError, match="axes 1 and 2"):
        ik.SRSInverseKinematics(dataclasses.replace(iiwa, joint_transforms=transforms))
    transforms = iiwa.joint_transforms.copy()
    transforms[6, 0, 3] += 1e-3  # axis 7 off the wrist centre
    with pytest.raises(ValueError, match="axis 7"):
        ik.SRSInverseKinematics(dataclasses.replace(iiwa, joint_transforms=transforms))


# --------------------------------------------------------------------------- singular poses


def test_home_configuration_is_singular_everywhere(iiwa, solver):
    solutions, branches = solver.solve(pose_of(iiwa, np.zeros(7)), return_branches=True)
    np.testing.assert_allclose(solutions, np.zeros((1, 7)), atol=1e-12)
    np.testing.assert_array_equal(branches, [[0, 0, 0]])


def test_wrist_singular_splits_free_angle(iiwa, solver):
    q = np.array([0.3, 0.5, 0.0, 1.0, 0.4, 0.0, 0.9])  # q6 = 0: axes 5 and 7 aligned
    pose = pose_of(iiwa, q)
    solutions, branches = solver.solve(pose, within_limits=False, return_branches=True)
    assert_valid(iiwa, solutions, pose)
    singular = solutions[branches[:, 2] == 0]
    assert len(singular) == 2  # the two shoulder-elbow branches that keep q6 = 0
    match = singular[np.argmin(np.abs(singular[:, :4] - q[:4]).max(axis=1))]
    np.testing.assert_allclose(match[[0, 1, 2, 3, 5]], q[[0, 1, 2, 3, 5]], atol=ANGLE_TOLERANCE)
    # only q5 + q7 is determined; it is split evenly
    np.testing.assert_allclose(match[4], match[6], atol=1e-12)
    np.testing.assert_allclose(match[4] + match[6], q[4] + q[6], atol=ANGLE_TOLERANCE)
    # branches distinct
    assert min(angular_distance(a, b) for a, b in itertools.combinations(solutions, 2)) > 1e-3


def test_wrist_singular_large_sum_stays_within_limits(iiwa, solver):
    q = np.array([0.3, 0.5, 0.0, 1.0, 1.6, 0.0, 1.5])  # q5 + q7 = 3.1 > the q7 limit
    pose = pose_of(iiwa, q)
    solutions = solver.solve(pose)
    assert len(solutions) >= 1
    assert_valid(iiwa, solutions, pose)


def test_elbow_stretched(iiwa, solver):
    q = np.array([0.3, 0.5, 0.0, 0.0, 0.4, 0.7, 0.9])
    pose = pose_of(iiwa, q)
    solutions, branches = solver.solve(pose, within_limits=False, return_branches=True)
    assert solutions.shape == (4, 7)  # elbow branches merged
    assert_valid(iiwa, solutions, pose)
    assert np.all(branches[:, 1] == 0)
    np.testing.assert_allclose(solutions[:, 3], 0.0, atol=1e-12)
    assert angular_distance(solutions, q).min() < ANGLE_TOLERANCE


def test_shoulder_singular_stretched_arm(iiwa, solver):
    q = np.array([0.3, 0.0, 0.0, 0.0, 0.4, 0.7, 0.9])  # q2 = q4 = 0: wrist centre on axis 1
    pose = pose_of(iiwa, q)
    solutions, branches = solver.solve(pose, return_branches=True)
    assert len(solutions) >= 1
    assert_valid(iiwa, solutions, pose)
    np.testing.assert_array_equal(solutions[:, 0], 0.0)  # the free angle q1 is set to 0
    assert np.all(branches[:, 0] == 0)


def wrist_on_axis1_pose(solver, height=0.9, rotation=None):
    """Flange pose putting the wrist centre on axis 1 at `height` (m) with a bent elbow."""
    rotation = spatial.rot_x(0.4) @ spatial.rot_z(1.0) if rotation is None else rotation
    home = solver.home
    wrist = np.array([solver.shoulder[0], solver.shoulder[1], height])
    return spatial.homogeneous(rotation @ home[:3, :3], wrist + rotation @ (home[:3, 3] - solver.wrist))


def test_shoulder_singular_bent_elbow(iiwa, solver):
    pose = wrist_on_axis1_pose(solver)
    solutions, branches = solver.solve(pose, within_limits=False, return_branches=True)
    assert solutions.shape == (4, 7)  # 2 elbow x 2 wrist, shoulder merged
    assert_valid(iiwa, solutions, pose)
    np.testing.assert_array_equal(solutions[:, 0], 0.0)
    assert np.all(branches[:, 0] == 0)
    # with joint 3 turned the forearm leaves the plane of axis 1: the wrist cannot reach the axis
    assert solver.solve(pose, q3=0.3, within_limits=False).shape == (0, 7)


@pytest.mark.parametrize("offset", [1e-13, 1e-11, 1e-10, 1e-9, 1e-7])
def test_near_singular_poses_are_finite_and_exact(iiwa, solver, offset):
    configurations = [
        [0.3, 0.5, 0.0, 1.0, 0.4, offset, 0.9],  # near wrist singular
        [0.3, 0.5, 0.0, offset, 0.4, 0.7, 0.9],  # near elbow stretched
        [0.3, offset, 0.0, offset, 0.4, 0.7, 0.9],  # near shoulder singular and stretched
        [0.3, offset, 0.3, offset, 0.4, offset, 0.9],  # all three, q3 = 0.3
    ]
    for q in configurations:
        pose = pose_of(iiwa, q)
        solutions = solver.solve(pose, q3=q[2], within_limits=False)
        assert len(solutions) >= 1
        assert_valid(iiwa, solutions, pose)
    pose = wrist_on_axis1_pose(solver)
    pose[0, 3] += offset  # wrist centre just off axis 1
    solutions = solver.solve(pose, within_limits=False)
    assert len(solutions) >= 4
    assert_valid(iiwa, solutions, pose)


def test_shoulder_singular_upright_arm_moves_free_angle_within_limits(iiwa, solver):
    # upright stretched arm: axes 1, 3 and 5 align, q1 + q5 = 3.0 rad exceeds the q5 limit alone
    q = np.array([1.5, 0.0, 0.0, 0.0, 1.5, 1.0, 0.0])
    pose = pose_of(iiwa, q)
    solutions = solver.solve(pose)
    assert len(solutions) >= 1
    assert_valid(iiwa, solutions, pose)
    assert np.all(iiwa.within_limits(solutions))
    assert np.all(solutions[:, 0] != 0.0)
    np.testing.assert_allclose(solutions[:, 0] + solutions[:, 4], 3.0, atol=1e-9)
    # without limits the free angle stays at q1 = 0
    unlimited = solver.solve(pose, within_limits=False)
    assert_valid(iiwa, unlimited, pose)
    np.testing.assert_array_equal(unlimited[:, 0], 0.0)


def test_shoulder_singular_any_orientation(iiwa, solver, rng):
    """Wrist centre on axis 1 in random orientations: valid, within limits; q1 = 0 unless moved."""
    moved = 0
    for _ in range(20):
        rotation = spatial.euler_zyx_to_matrix(
            rng.uniform(-np.pi, np.pi), rng.uniform(-1.5, 1.5), rng.uniform(-np.pi, np.pi)
        )
        pose = wrist_on_axis1_pose(solver, rng.uniform(0.5, 1.1), rotation)
        solutions = solver.solve(pose)
        assert_valid(iiwa, solutions, pose)
        assert np.all(iiwa.within_limits(solutions))
        moved += np.any(solutions[:, 0] != 0.0)
        unlimited = solver.solve(pose, within_limits=False)
        assert_valid(iiwa, unlimited, pose)
        np.testing.assert_array_equal(unlimited[:, 0], 0.0)
    assert moved > 0
