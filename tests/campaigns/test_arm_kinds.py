"""The kinds of arm and campaign real calibrations meet (`remaster.campaigns.arm_kinds`), simulated: each one's
tables are what its truth record says, it writes and reads back as a campaign folder, and it has
the property that makes it that kind. The truth's link errors are not the fit's model."""

import numpy as np
import pytest

from remaster import files, spatial
from remaster.campaigns import arm_kinds, folders, scenario, simulation
from remaster.robot import kinematics, planning

from ..conftest import REPO

_simulated = {}


def simulated(kind: str):
    """(scenario, nominal chain, SimulatedCampaign) of a kind, simulated once per session."""
    if kind not in _simulated:
        spec = arm_kinds.KINDS[kind]()
        chain = arm_kinds.chain_of(spec, REPO)
        _simulated[kind] = (spec, chain, scenario.simulate(spec, chain))
    return _simulated[kind]


def joints(chain):
    return [f"q{j + 1}" for j in range(chain.n_joints)]


def true_points(out, sensor: str) -> np.ndarray:
    return np.array(out.truth["sensors"][sensor]["true_marker_positions_robot_frame_m"])


@pytest.mark.parametrize("kind", sorted(arm_kinds.KINDS))
def test_each_kind_writes_and_reads_back_as_a_campaign_folder(kind, tmp_path):
    spec, chain, out = simulated(kind)
    folder = folders.write_campaign(tmp_path / spec["name"], out.metadata, out.tables)
    campaign = folders.read_campaign(folder, repo_root=REPO)
    assert list(campaign.sensors) == list(spec["sensors"]) == list(out.tables)
    assert campaign.chain.n_joints == chain.n_joints
    for name, sensor in campaign.sensors.items():
        table = sensor.table
        assert table.groupby("set").size().to_dict() == {
            "optimization": arm_kinds.OPTIMIZATION,
            "validation": arm_kinds.VALIDATION,
        }
        assert not any(f"q{chain.n_joints + 1}" == c for c in table.columns)
        columns = joints(chain) + ["x", "y", "z"]
        np.testing.assert_array_equal(table[columns].to_numpy(), out.tables[name][columns].to_numpy())
        np.testing.assert_array_equal(sensor.marker, spec["sensors"][name]["marker"])


@pytest.mark.parametrize("kind", sorted(arm_kinds.KINDS))
def test_each_kinds_truth_record_gives_back_its_robot_and_measurements(kind, tmp_path):
    """From the truth file as written (JSON), the true robot reproduces the recorded marker
    positions exactly, and the tables are those positions seen by the sensor plus its noise."""
    spec, chain, out = simulated(kind)
    truth = files.read_json(files.write_json(tmp_path / "truth.json", out.truth))
    robot = scenario.robot_from_truth(truth)
    for name, table in out.tables.items():
        sensor = scenario.sensor_from_truth(truth, name, spec["sensors"][name]["marker"])
        q = table[joints(chain)].to_numpy()
        elapsed = np.arange(len(q)) * spec["plan"]["seconds_per_configuration"]
        recorded = true_points(out, name)
        np.testing.assert_allclose(
            simulation.true_marker_positions(chain, robot, sensor, q, elapsed), recorded, rtol=0, atol=1e-13
        )
        seen = table[["x", "y", "z"]].notna().all(axis=1).to_numpy()
        error = (
            table[["x", "y", "z"]].to_numpy()[seen] - spatial.transform_points(sensor.robot_to_sensor, recorded)[seen]
        )
        assert np.abs(error).max() < 5 * sensor.noise and np.abs(error).max() > 0.5 * sensor.noise


def test_a_joint_never_moved_is_held_at_zero_everywhere():
    _, chain, out = simulated("joint_never_moved")
    q = out.tables["laser_tracker"][joints(chain)].to_numpy()
    np.testing.assert_array_equal(q[:, 2], 0.0)
    assert np.all(np.degrees(np.delete(q, 2, axis=1).std(axis=0)) > 20.0)  # every other joint moves
    assert "held_joints_rad" not in out.truth["planning"]  # the default, recorded as it always was


def test_joints_one_and_seven_held_at_zero_and_the_rest_move_within_the_checks():
    _, chain, out = simulated("joints_one_and_seven_held")
    q = out.tables["laser_tracker"][joints(chain)].to_numpy()
    np.testing.assert_array_equal(q[:, [0, 6]], 0.0)
    assert np.all(np.degrees(q[:, 1:6].std(axis=0)) > 20.0)
    assert np.all(chain.within_limits(q))
    model = planning.CollisionModel()
    above, apart = planning.collision_free(chain, q, model)
    sensor = out.truth["sensors"]["laser_tracker"]
    sight = planning.SightLine(np.array(sensor["pose_in_robot"])[:3, 3], np.array(arm_kinds.TRACKER["marker"]))
    assert above.all() and apart.all() and planning.marker_visible(chain, q, sight, model).all()
    assert out.truth["planning"]["design"] == "random_joints"
    assert out.truth["planning"]["held_joints_rad"] == {"q1": 0.0, "q7": 0.0}
    assert (out.tables["laser_tracker"]["solution"] == 0).all()  # each configuration its own pose


def test_a_marker_1_mm_from_the_last_axis_moves_2_mm_when_joint_7_turns_half_a_turn():
    spec, chain, out = simulated("marker_near_last_axis")
    marker = np.array(spec["sensors"]["laser_tracker"]["marker"])
    in_last_joint = spatial.transform_points(chain.tool_transform, marker)
    axis = chain.joint_axes[-1]
    assert np.linalg.norm(in_last_joint - (in_last_joint @ axis) * axis) == pytest.approx(1e-3, abs=1e-12)
    q = out.tables["laser_tracker"][joints(chain)].to_numpy()
    turned = q + np.r_[np.zeros(6), np.pi]
    moved = kinematics.marker_positions(chain, turned, marker) - kinematics.marker_positions(chain, q, marker)
    np.testing.assert_allclose(np.linalg.norm(moved, axis=1), 2e-3, rtol=0, atol=1e-12)


def test_only_25_configurations_in_the_optimization_set():
    _, _, out = simulated("few_configurations")
    table = out.tables["laser_tracker"]
    optimization = table[table["set"] == "optimization"]
    assert len(optimization) == 25 and optimization["pose"].nunique() == 5


def test_three_reflectors_of_one_tracker_are_three_sensors_with_one_pose():
    spec, chain, out = simulated("three_reflectors")
    names = list(arm_kinds.REFLECTORS)
    assert list(out.tables) == names and out.metadata["sensors"].keys() == set(names)
    first = out.tables[names[0]]
    for name in names[1:]:
        np.testing.assert_array_equal(out.tables[name][joints(chain)].to_numpy(), first[joints(chain)].to_numpy())
        assert out.tables[name]["time"].equals(first["time"])
        assert out.truth["sensors"][name]["T_NR"] == out.truth["sensors"][names[0]]["T_NR"]
    # no link errors: the three true positions keep the plate's triangle, 100 mm sqrt(3) a side
    points = [true_points(out, name) for name in names]
    for a, b in ((0, 1), (1, 2), (0, 2)):
        side = np.linalg.norm(np.subtract(arm_kinds.REFLECTORS[names[a]], arm_kinds.REFLECTORS[names[b]]))
        assert side == pytest.approx(0.1732, abs=1e-4)
        np.testing.assert_allclose(np.linalg.norm(points[a] - points[b], axis=1), side, rtol=0, atol=1e-12)


def test_a_dh_arm_with_dh_errors_is_its_perturbed_table():
    spec, chain, out = simulated("ur5_with_dh_errors")
    table = out.tables["laser_tracker"]
    q = table[joints(chain)].to_numpy()
    assert chain.n_joints == 6 and np.all(np.degrees(q.std(axis=0)) > 20.0)
    record = out.truth["effects"]["dh_errors"]
    std = np.array(spec["truth"]["dh_errors"]["std"])
    # drawn from their own seed: the scenario's seed does not change the robot
    np.testing.assert_array_equal(record["errors"], np.random.default_rng(5).normal(0.0, std, (6, 4)))
    np.testing.assert_array_equal(record["nominal_rows"], spec["robot"]["dh"]["rows"])
    true_table = np.array(spec["robot"]["dh"]["rows"]) + np.array(record["errors"])
    true_arm = kinematics.chain_from_dh(true_table, "standard")
    offsets = np.radians(spec["truth"]["zero_offsets_deg"])
    marker = np.array(spec["sensors"]["laser_tracker"]["marker"])
    expected = kinematics.marker_positions(true_arm, q + offsets, marker)
    np.testing.assert_allclose(true_points(out, "laser_tracker"), expected, rtol=0, atol=1e-13)
    nominal = kinematics.marker_positions(chain, q + offsets, marker)
    assert 5e-5 < np.abs(expected - nominal).max() < 5e-3  # errors of the stated size moved the marker


def test_the_iiwa_dh_table_is_its_urdf_chain_without_masses():
    urdf = arm_kinds.chain_of({"name": "urdf", "robot": arm_kinds.IIWA}, REPO)
    dh = kinematics.chain_from_dh(arm_kinds.IIWA_DH, "standard")
    q = np.random.default_rng(3).uniform(urdf.lower, urdf.upper, (200, 7))
    assert kinematics.max_chain_difference(urdf, dh, q) < 1e-12
    assert urdf.inertias is not None and dh.inertias is None


def _by_hand(chain, motions, q, marker) -> np.ndarray:
    """Marker positions (n, 3) of the chain with F'_j = Trans(t_j) RPY(r_j) F_j, by matrix products."""
    moved = [
        spatial.homogeneous(spatial.rpy_to_matrix(*m[3:]), m[:3]) @ f
        for m, f in zip(motions, [*chain.joint_transforms, chain.tool_transform])
    ]
    out = []
    for row in q:
        pose = np.eye(4)
        for j in range(chain.n_joints):
            pose = pose @ moved[j] @ spatial.homogeneous(spatial.rot_axis(chain.joint_axes[j], row[j]))
        out.append(spatial.transform_points(pose @ moved[-1], marker))
    return np.array(out)


def test_an_iiwa_with_rigid_link_errors_and_every_joint_moving():
    spec, chain, out = simulated("iiwa_rigid_link_errors")
    q = out.tables["laser_tracker"][joints(chain)].to_numpy()
    assert np.all(np.degrees(q.std(axis=0)) > 20.0)  # joint 3 too
    assert np.all(chain.within_limits(q))
    for _, pose in out.tables["laser_tracker"].groupby(["set", "pose"]):  # one q3 per pose
        assert pose["q3"].nunique() == 1
    assert out.truth["planning"]["held_joints_rad"] == {}
    sizes = spec["truth"]["link_errors"]
    draw = np.random.default_rng(sizes["seed"])
    expected = np.hstack(
        [draw.normal(0, sizes["translation_std"], (8, 3)), draw.normal(0, sizes["rotation_std"], (8, 3))]
    )
    motions = out.truth["effects"]["link_motions"]
    np.testing.assert_array_equal(np.hstack([motions["translations_m"], motions["rotations_rpy_rad"]]), expected)
    marker = np.array(spec["sensors"]["laser_tracker"]["marker"])
    by_hand = _by_hand(chain, expected, q + np.radians(spec["truth"]["zero_offsets_deg"]), marker)
    np.testing.assert_allclose(true_points(out, "laser_tracker"), by_hand, rtol=0, atol=1e-13)
