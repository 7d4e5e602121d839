"""The pose planner: its configurations satisfy every constraint it claims to check."""

import numpy as np
import pytest

from remaster.errors import InputError
from remaster.robot import kinematics, planning

SENSOR = np.array([1.6, 0.5, 1.0])
MARKER = np.array([-0.1, 0.0, 0.02])


@pytest.fixture(scope="module")
def plan(iiwa):
    rng = np.random.default_rng(7)
    sights = [planning.SightLine(SENSOR, MARKER), planning.SightLine(np.array([1.6, 0.3, 1.6]), -MARKER)]
    return planning.plan_set(iiwa, "optimization", SENSOR, sights, rng, size=planning.SetSize(60)), sights


def test_latin_hypercube_has_one_sample_per_stratum(rng):
    u = planning.latin_hypercube(60, 4, rng)
    assert u.shape == (60, 4) and np.all((u >= 0) & (u < 1))
    for column in u.T:
        assert sorted(np.floor(column * 60).astype(int)) == list(range(60))


def test_pointing_pose_aims_tool_z_at_target(rng):
    for _ in range(20):
        position, target = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3) + [3, 0, 0]
        pose = planning.pointing_pose(position, target, rng.uniform(-np.pi, np.pi))
        direction = (target - position) / np.linalg.norm(target - position)
        np.testing.assert_allclose(pose[:3, 2], direction, atol=1e-12)
        np.testing.assert_allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3), atol=1e-12)
        assert np.linalg.det(pose[:3, :3]) == pytest.approx(1.0)


def test_candidate_poses_span_the_paper_workspace(rng):
    poses = planning.candidate_poses(60, SENSOR, rng)
    radius = np.linalg.norm(poses[:, :2, 3], axis=1)
    assert np.all((radius >= 0.2) & (radius <= 0.5))
    assert np.all((poses[:, 2, 3] >= 0.4) & (poses[:, 2, 3] <= 0.8))


def test_plan_configurations_satisfy_every_constraint(iiwa, plan):
    plan, sights = plan
    q = plan.table[[f"q{j}" for j in range(1, 8)]].to_numpy()
    assert 20 <= plan.table["pose"].nunique() <= 60 and len(q) > 60
    assert np.all(iiwa.within_limits(q))
    above, apart = planning.collision_free(iiwa, q, planning.CollisionModel())
    assert above.all() and apart.all()
    for sight in sights:
        assert planning.marker_visible(iiwa, q, sight, planning.CollisionModel()).all()
    np.testing.assert_allclose(q[:, 2], 0.0)  # the redundancy is held at q3 = 0
    # every configuration of a pose reaches the same flange pose, tool Z at the sensor
    poses = kinematics.flange_poses(iiwa, q)
    for _, group in plan.table.groupby("pose"):
        same = poses[group.index]
        np.testing.assert_allclose(same, np.broadcast_to(same[0], same.shape), atol=1e-9)
        direction = SENSOR - same[0, :3, 3]
        np.testing.assert_allclose(same[0, :3, 2], direction / np.linalg.norm(direction), atol=1e-9)
    # solutions of one pose are distinct configurations
    assert len(np.unique(q.round(9), axis=0)) == len(q)


def test_plan_is_a_nearest_neighbour_tour(plan):
    plan, _ = plan
    q = plan.table[[f"q{j}" for j in range(1, 8)]].to_numpy()
    order = planning.nearest_neighbour_tour(q, start=np.zeros(7))
    np.testing.assert_array_equal(order, np.arange(len(q)))


def test_exact_sizes_are_met(iiwa):
    rng = np.random.default_rng(3)
    plan = planning.plan_set(
        iiwa,
        "validation",
        SENSOR,
        [planning.SightLine(SENSOR, MARKER)],
        rng,
        size=planning.SetSize(60, poses=20, configurations=90),
    )
    assert plan.table["pose"].nunique() == 20 and len(plan.table) == 90
    assert (plan.table["set"] == "validation").all()


def test_choose_poses_subset_sum():
    counts = [8, 1, 4, 4, 2, 8, 6]
    chosen = planning.choose_poses(counts, 3, 10)
    assert len(chosen) == 3 and sum(counts[i] for i in chosen) == 10
    assert list(chosen) == [2, 3, 4]  # the earliest subset (4 + 4 + 2)
    with pytest.raises(InputError, match="exactly 100"):
        planning.choose_poses(counts, 3, 100)


def test_collision_checks_catch_floor_and_folded_wrist(iiwa):
    q = np.radians(
        [
            [0, 120, 0, 0, 0, 0, 0],  # bent down through the floor
            [0, 0, 0, -120, 0, -120, 0],  # wrist folded back onto the forearm
            [0, 0, 0, 0, 0, 0, 0],
        ]
    )  # upright
    above, apart = planning.collision_free(iiwa, q, planning.CollisionModel())
    np.testing.assert_array_equal(above, [False, True, True])
    np.testing.assert_array_equal(apart, [True, False, True])


def test_marker_hidden_by_a_link_or_facing_away(iiwa):
    """Arm straight up, marker on the tool plate: a sensor on the far side of the upper arm is blocked."""
    q = np.zeros((1, 7))
    model = planning.CollisionModel()
    marker = kinematics.marker_positions(iiwa, q, MARKER)[0]
    tool_z = kinematics.flange_poses(iiwa, q)[0, :3, 2]
    ahead = planning.SightLine(marker + 2.0 * tool_z, MARKER)
    assert planning.marker_visible(iiwa, q, ahead, model).all()
    behind = planning.SightLine(marker - 2.0 * tool_z, MARKER)
    assert not planning.marker_visible(iiwa, q, behind, model).any()
    # looking down the arm from straight below the marker, past the links, within the acceptance cone
    through_arm = planning.SightLine(np.array([marker[0] * 0.2, 0.0, -1.0]), MARKER, acceptance=np.pi)
    assert not planning.marker_visible(iiwa, q, through_arm, model).any()


def test_segment_distances_match_brute_force(rng):
    for k in range(100):
        a0, a1, b0, b1 = rng.normal(size=(4, 3))
        if k % 5 == 0:
            a1 = a0.copy()  # a point
        s = np.linspace(0, 1, 301)
        brute = np.linalg.norm(
            (a0 + s[:, None] * (a1 - a0))[:, None] - (b0 + s[:, None] * (b1 - b0))[None], axis=-1
        ).min()
        distance = planning.segment_distances(a0, a1, b0, b1)
        assert distance <= brute + 1e-12 and distance >= brute - 1e-3


def test_iso9283_points_lie_on_the_diagonal_plane_a_tenth_of_a_diagonal_from_its_corners():
    centre, edge = np.array([0.3, -0.1, 0.6]), 0.25
    points = planning.iso9283_points(centre, edge)
    np.testing.assert_allclose(points[0], centre, atol=1e-15)  # P1
    corners = centre + edge / 2 * np.array([[-1, -1, -1], [-1, 1, -1], [1, 1, 1], [1, -1, 1]])
    normal = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    np.testing.assert_allclose((points - centre) @ normal, 0.0, atol=1e-15)
    diagonal = edge * np.sqrt(3.0)
    np.testing.assert_allclose(np.linalg.norm(points[1:] - corners, axis=1), 0.1 * diagonal, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(points[1:] - centre, axis=1), 0.4 * diagonal, atol=1e-15)
    # the plane holds the lower -x edge and the upper +x edge: it rises along x, level along y
    assert normal[1] == 0.0 and normal[0] * normal[2] < 0


def test_cube_plan_has_one_flange_orientation_and_the_designed_positions(iiwa):
    cubes = [(np.array([-0.35, 0.0, 0.7]), 0.2), (np.array([0.0, 0.35, 0.68]), 0.2)]
    rotation = planning.cube_orientation([c for c, _ in cubes], SENSOR, tool_angle=0.3)
    direction = SENSOR - np.mean([c for c, _ in cubes], axis=0)
    np.testing.assert_allclose(rotation[:, 2], direction / np.linalg.norm(direction), atol=1e-12)
    sights = [planning.SightLine(SENSOR, MARKER)]
    plan = planning.plan_cubes(iiwa, "validation", cubes, rotation, sights)
    table = plan.table
    assert list(table.columns) == ["set", "pose", "solution"] + [f"q{j}" for j in range(1, 8)]
    assert (table["set"] == "validation").all() and plan.candidates == 10
    assert table["pose"].nunique() + plan.discarded["unreachable_poses"] == 10
    assert table["pose"].nunique() >= 6 and len(table) > table["pose"].nunique()
    q = table[[f"q{j}" for j in range(1, 8)]].to_numpy()
    flange = kinematics.flange_poses(iiwa, q)
    np.testing.assert_allclose(flange[:, :3, :3], np.broadcast_to(rotation, (len(q), 3, 3)), atol=1e-9)
    designed = np.concatenate([planning.iso9283_points(c, e) for c, e in cubes])
    gaps = np.linalg.norm(flange[:, None, :3, 3] - designed[None], axis=2)
    assert gaps.min(axis=1).max() < 1e-9  # every configuration reaches a designed point
    for _, group in table.groupby("pose"):  # the solutions of one pose reach one point
        assert len(set(gaps[group.index].argmin(axis=1))) == 1
    # the same checks as the Latin-hypercube plan, and the same tour
    assert np.all(iiwa.within_limits(q))
    above, apart = planning.collision_free(iiwa, q, planning.CollisionModel())
    assert above.all() and apart.all() and planning.marker_visible(iiwa, q, sights[0], planning.CollisionModel()).all()
    np.testing.assert_array_equal(planning.nearest_neighbour_tour(q, start=np.zeros(7)), np.arange(len(q)))


def test_a_free_q3_is_drawn_for_each_pose_within_its_limits(iiwa):
    sights = [planning.SightLine(SENSOR, MARKER)]
    plan = planning.plan_set(
        iiwa, "optimization", SENSOR, sights, np.random.default_rng(3), size=planning.SetSize(30), q3=planning.FREE
    )
    table = plan.table
    assert table["q3"].groupby(table["pose"]).nunique().eq(1).all()  # the solutions of a pose share it
    per_pose = table.groupby("pose")["q3"].first().to_numpy()
    assert len(np.unique(per_pose)) == len(per_pose) >= 10
    assert np.all(np.abs(per_pose) <= iiwa.upper[2]) and np.degrees(per_pose.std()) > 40.0
    q = table[[f"q{j}" for j in range(1, 8)]].to_numpy()
    poses = kinematics.flange_poses(iiwa, q)
    for _, group in table.groupby("pose"):
        same = poses[group.index]
        np.testing.assert_allclose(same, np.broadcast_to(same[0], same.shape), atol=1e-9)
    with pytest.raises(ValueError, match="Generator"):
        planning.plan_cubes(
            iiwa, "validation", [(np.array([0.0, 0.35, 0.68]), 0.2)], np.eye(3), sights, q3=planning.FREE
        )


def test_random_joint_plans_hold_the_held_joints_and_pass_every_check(iiwa):
    sights = [planning.SightLine(SENSOR, MARKER)]
    model = planning.CollisionModel()
    plan = planning.plan_random(
        iiwa, "validation", sights, np.random.default_rng(4), n_configurations=30, held={0: 0.0, 6: 0.5}
    )
    table = plan.table
    q = table[[f"q{j}" for j in range(1, 8)]].to_numpy()
    assert len(q) == 30 and table["pose"].tolist() == list(range(30)) and (table["solution"] == 0).all()
    np.testing.assert_array_equal(q[:, 0], 0.0)
    np.testing.assert_array_equal(q[:, 6], 0.5)
    assert np.all(iiwa.within_limits(q))
    above, apart = planning.collision_free(iiwa, q, model)
    assert above.all() and apart.all() and planning.marker_visible(iiwa, q, sights[0], model).all()
    # whole batches of 200 drawn; those not discarded are at least the 30 kept
    assert plan.candidates % 200 == 0 and plan.candidates - sum(plan.discarded.values()) >= 30
    np.testing.assert_array_equal(planning.nearest_neighbour_tour(q, start=np.zeros(7)), np.arange(30))
    with pytest.raises(InputError, match="50 batches of 5 random configurations gave 0 that pass"):
        planning.plan_random(  # a floor above the arm: no configuration passes
            iiwa,
            "validation",
            sights,
            np.random.default_rng(4),
            n_configurations=30,
            candidates=5,
            model=planning.CollisionModel(floor_height=5.0),
        )


def test_joint_ranges_are_the_limits_or_a_turn(iiwa, ur5_dh):
    assert planning.joint_range(iiwa, 1) == (iiwa.lower[1], iiwa.upper[1])
    assert planning.joint_range(ur5_dh, 0) == (-np.pi, np.pi)
