"""The simulator: measurements are the true model seen from the sensor, campaigns are
deterministic and pass the reader, and the bundled twin is sized like the paper."""

import copy
import hashlib
import itertools

import numpy as np
import pandas as pd
import pytest

from remaster import files, spatial
from remaster.campaigns import folders, scenario, simulation
from remaster.campaigns.simulation import Sensor, TrueRobot, looking_at, measure, true_joint_angles
from remaster.errors import InputError
from remaster.robot import kinematics, planning
from remaster.robot.gravity import gravity_torques

from ..conftest import REPO

SCENARIOS = REPO / "data" / "simulation"


def small_scenario(**truth):
    """kuka-twin's scenario with small sets, for speed."""
    spec = files.read_yaml(SCENARIOS / "kuka-twin.yaml")
    spec["plan"]["sets"] = {
        "optimization": {"poses": 6, "configurations": 25},
        "validation": {"poses": 4, "configurations": 16},
    }
    spec["truth"].update(truth)
    return spec


def test_noise_free_measurement_is_true_kinematics_in_sensor_frame(iiwa, rng):
    q = rng.uniform(iiwa.lower, iiwa.upper, (40, 7))
    robot = TrueRobot(zero_offsets=np.radians([0.4, -0.2, 0.1, 0.1, 0.4, -0.1, 0.9]))
    sensor = Sensor("lt", "laser_tracker", looking_at([1.6, 0.5, 1.0], [0, 0, 0.6]), 0.0, np.array([-0.1, 0, 0.02]))
    expected = spatial.transform_points(
        spatial.invert(sensor.pose_in_robot), kinematics.marker_positions(iiwa, q + robot.zero_offsets, sensor.marker)
    )
    np.testing.assert_allclose(measure(iiwa, robot, sensor, q, rng), expected, atol=1e-12)


def test_noise_has_the_stated_size(iiwa, rng):
    q = rng.uniform(iiwa.lower, iiwa.upper, (2000, 7))
    robot = TrueRobot(zero_offsets=np.zeros(7))
    sensor = Sensor("mc", "motion_capture", looking_at([1.6, 0.3, 1.6], [0, 0, 0.6]), 3e-5, np.array([0.1, 0, 0.02]))
    clean = measure(iiwa, robot, Sensor(**{**sensor.__dict__, "noise": 0.0}), q, rng)
    error = measure(iiwa, robot, sensor, q, rng) - clean
    assert np.std(error) == pytest.approx(3e-5, rel=0.05)
    assert np.abs(np.mean(error, axis=0)).max() < 4 * 3e-5 / np.sqrt(2000)


def test_every_effect_changes_the_measurement_as_modelled(iiwa, rng):
    q = rng.uniform(iiwa.lower, iiwa.upper, (30, 7))
    base = TrueRobot(zero_offsets=np.zeros(7))
    compliance = np.array([0, 2.5e-5, 0, 3e-5, 0, 5e-5, 0])
    compliant = TrueRobot(zero_offsets=np.zeros(7), joint_compliance=compliance, payload_mass=1.2)
    tau = gravity_torques(iiwa, q, payload_mass=1.2)
    np.testing.assert_allclose(true_joint_angles(iiwa, compliant, q), q + compliance * tau, atol=1e-15)
    scaled = TrueRobot(zero_offsets=np.zeros(7), joint_scale=np.full(7, 1e-3))
    np.testing.assert_allclose(true_joint_angles(iiwa, scaled, q), 1.001 * q)
    drifting = TrueRobot(zero_offsets=np.zeros(7), drift_rate=np.full(7, 1e-6))
    np.testing.assert_allclose(true_joint_angles(iiwa, drifting, q, elapsed_s=np.full(30, 3600.0)), q + 3.6e-3)
    with pytest.raises(ValueError, match="time"):
        true_joint_angles(iiwa, drifting, q)

    pose = looking_at([1.6, 0.5, 1.0], [0, 0, 0.6])
    nominal = Sensor("s", "other", pose, 0.0, np.array([0.1, 0, 0.02]))
    reference = measure(iiwa, base, nominal, q, rng)
    scaled_sensor = Sensor("s", "other", pose, 0.0, nominal.marker, scale_error=1e-3)
    np.testing.assert_allclose(measure(iiwa, base, scaled_sensor, q, rng), 1.001 * reference, atol=1e-15)
    moved_marker = Sensor("s", "other", pose, 0.0, nominal.marker, marker_error=np.array([0, 0, 1e-3]))
    shift = np.linalg.norm(measure(iiwa, base, moved_marker, q, rng) - reference, axis=1)
    np.testing.assert_allclose(shift, 1e-3, rtol=1e-9)  # a rigid 1 mm move of the marker


def test_simulated_campaign_is_deterministic_and_passes_the_reader(iiwa, tmp_path):
    spec = small_scenario()
    first = scenario.simulate(spec, iiwa)
    second = scenario.simulate(copy.deepcopy(spec), iiwa)
    digests = []
    for run, out in enumerate((first, second)):
        folders.write_campaign(tmp_path / str(run) / spec["name"], out.metadata, out.tables)
        files.write_json(tmp_path / str(run) / "truth.json", out.truth)
        digests.append(
            {
                p.name: hashlib.sha256(p.read_bytes()).hexdigest()
                for p in sorted((tmp_path / str(run)).rglob("*"))
                if p.is_file()
            }
        )
    assert digests[0] == digests[1]
    campaign = folders.read_campaign(tmp_path / "0" / spec["name"], repo_root=REPO)
    assert set(campaign.sensors) == {"motion_capture", "laser_tracker"}
    lt = campaign.sensors["laser_tracker"]
    assert len(lt.table) == 41 and lt.n_missing == 2  # the scenario's unseen points are kept
    assert lt.missing_rows.tolist() == first.truth["sensors"]["laser_tracker"]["unseen_rows"]
    other_seed = scenario.simulate(spec, iiwa, seed=1)
    assert not np.allclose(other_seed.tables["laser_tracker"]["q1"], first.tables["laser_tracker"]["q1"])


def test_truth_records_every_effect(iiwa):
    out = scenario.simulate(small_scenario(joint_scale=[1e-4] * 7, drift_deg_per_hour=[0.01] + [0.0] * 6), iiwa)
    assert set(out.truth["effects"]) == {"joint_compliance", "link_motions", "joint_scale", "drift"}
    np.testing.assert_allclose(out.truth["zero_offsets_deg"], [0.477, -0.192, 0.139, 0.099, 0.392, -0.114, 0.936])
    assert "truth" not in out.metadata and "effects" not in str(out.metadata)


def test_measurements_equal_truth_record_in_sensor_frame(iiwa):
    """The truth file's marker positions, seen through T_NR, are the measurements up to the noise."""
    out = scenario.simulate(small_scenario(), iiwa)
    for name, table in out.tables.items():
        truth = out.truth["sensors"][name]
        expected = spatial.transform_points(
            np.array(truth["T_NR"]), np.array(truth["true_marker_positions_robot_frame_m"])
        )
        seen = table[["x", "y", "z"]].notna().all(axis=1).to_numpy()
        error = table[["x", "y", "z"]].to_numpy()[seen] - expected[seen]
        assert np.abs(error).max() < 5 * truth["noise_m"]


@pytest.mark.parametrize("name", ["kuka-twin", "kuka-twin-2019", "kuka-compliance"])
def test_bundled_campaigns_read_and_twin_is_sized_like_the_paper(name):
    campaign = folders.read_campaign(REPO / "data" / "raw" / name, repo_root=REPO)
    for sensor in campaign.sensors.values():
        table = sensor.table
        sizes = {
            s: (table[table["set"] == s]["pose"].nunique(), int((table["set"] == s).sum()))
            for s in ("optimization", "validation")
        }
        assert sizes == {"optimization": (36, 173), "validation": (32, 156)}
    assert (set(campaign.sensors) == {"laser_tracker"}) == (name == "kuka-compliance")


def test_bundled_campaigns_are_what_the_scenarios_generate(iiwa):
    """The committed kuka-twin is exactly what `remaster simulate` makes from its scenario."""
    out = scenario.simulate(files.read_yaml(SCENARIOS / "kuka-twin.yaml"), iiwa)
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-twin", repo_root=REPO)
    for name, table in out.tables.items():
        stored = campaign.sensors[name].table
        # equal up to rounding, so that a change in the order of floating-point operations
        # does not force regenerating the data; regenerating with the same code is byte-identical
        np.testing.assert_allclose(
            stored[["x", "y", "z"]].to_numpy(), table[["x", "y", "z"]].to_numpy(), rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(
            stored[[f"q{j}" for j in range(1, 8)]].to_numpy(),
            table[[f"q{j}" for j in range(1, 8)]].to_numpy(),
            rtol=0,
            atol=1e-12,
        )


def _cubes_of(spec, set_name):
    return [(np.array(c["centre"]), c["edge"]) for c in spec["plan"]["sets"][set_name]["cubes"]]


def test_cube_scenario_is_deterministic_and_matches_the_bundled_campaign(iiwa):
    spec = files.read_yaml(SCENARIOS / "kuka-cubes.yaml")
    first = scenario.simulate(spec, iiwa)
    second = scenario.simulate(copy.deepcopy(spec), iiwa)
    assert first.truth == second.truth
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-cubes", repo_root=REPO)
    assert set(campaign.sensors) == set(first.tables) == {"motion_capture", "laser_tracker"}
    for name, table in first.tables.items():
        pd.testing.assert_frame_equal(table, second.tables[name])
        stored = campaign.sensors[name].table
        columns = [f"q{j}" for j in range(1, 8)] + ["x", "y", "z"]
        np.testing.assert_allclose(stored[columns].to_numpy(), table[columns].to_numpy(), rtol=0, atol=1e-12)
        assert stored["set"].tolist() == table["set"].tolist()
    assert campaign.sensors["laser_tracker"].n_missing == 2


def test_bundled_cube_campaign_has_one_orientation_on_the_designed_cubes(iiwa):
    spec = files.read_yaml(SCENARIOS / "kuka-cubes.yaml")
    twin = files.read_yaml(SCENARIOS / "kuka-twin.yaml")
    assert spec["robot"] == twin["robot"] and spec["truth"] == twin["truth"] and spec["sensors"] == twin["sensors"]
    truth = files.read_json(REPO / "data" / "truth" / "kuka-cubes.json")
    assert truth["effects"] == files.read_json(REPO / "data" / "truth" / "kuka-twin.json")["effects"]  # the same links
    rotation = np.array(truth["planning"]["flange_rotation"])
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-cubes", repo_root=REPO)
    table = campaign.sensors["laser_tracker"].table
    centres = {}
    for set_name in ("optimization", "validation"):
        rows = table[table["set"] == set_name]
        assert rows["pose"].nunique() >= 30 and 140 <= len(rows) <= 190
        q = rows[[f"q{j}" for j in range(1, 8)]].to_numpy()
        flange = kinematics.flange_poses(iiwa, q)
        np.testing.assert_allclose(flange[:, :3, :3], np.broadcast_to(rotation, (len(q), 3, 3)), atol=1e-9)
        cubes = _cubes_of(spec, set_name)
        designed = np.concatenate([planning.iso9283_points(c, e) for c, e in cubes])
        gaps = np.linalg.norm(flange[:, None, :3, 3] - designed[None], axis=2)
        assert gaps.min(axis=1).max() < 1e-9
        centres[set_name] = {tuple(c) for c, _ in cubes}
        for centre, edge in cubes:  # every cube wholly inside kuka-twin's workspace
            corners = centre + edge / 2 * np.array(list(itertools.product([-1, 1], repeat=3)))
            square = centre[:2] + edge / 2 * np.clip(-centre[:2] / (edge / 2), -1, 1)  # nearest point to the axis
            assert np.linalg.norm(corners[:, :2], axis=1).max() <= 0.5 and np.linalg.norm(square) >= 0.2
            assert corners[:, 2].min() >= 0.4 and corners[:, 2].max() <= 0.8
    assert not centres["optimization"] & centres["validation"]


def test_an_unknown_plan_design_is_refused(iiwa):
    spec = files.read_yaml(SCENARIOS / "kuka-cubes.yaml")
    spec["plan"]["design"] = "iso9283_cube"
    with pytest.raises(InputError, match="plan/design: unknown design 'iso9283_cube'"):
        scenario.simulate(spec, iiwa)
    spec["plan"]["design"] = "iso9283_cubes"
    spec["plan"]["sets"]["validation"]["cubes"][1] = {"centre": [0.1, 0.3], "edge": 0.2}
    with pytest.raises(InputError, match="plan/sets/validation/cubes/1"):
        scenario.simulate(spec, iiwa)


def test_a_rigid_motion_of_the_first_transform_moves_the_whole_arm_in_the_base_frame(iiwa, rng):
    """F'_1 = Trans(t) RPY(r) F_1 is written in the frame F_1 starts from, the base: a translation
    shifts every marker by t, a yaw turns every marker about the base z axis."""
    q = rng.uniform(iiwa.lower, iiwa.upper, (20, 7))
    sensor = Sensor("lt", "laser_tracker", np.eye(4), 0.0, np.array([-0.1, 0.0, 0.02]))
    nominal = simulation.true_marker_positions(iiwa, TrueRobot(zero_offsets=np.zeros(7)), sensor, q)
    motions = np.zeros((8, 6))
    motions[0, :3] = [1e-3, -2e-3, 0.5e-3]
    shifted = simulation.true_marker_positions(iiwa, TrueRobot(np.zeros(7), link_motions=motions), sensor, q)
    np.testing.assert_allclose(shifted - nominal, np.broadcast_to([1e-3, -2e-3, 0.5e-3], nominal.shape), atol=1e-15)
    motions = np.zeros((8, 6))
    motions[0, 5] = 2e-3  # yaw
    turned = simulation.true_marker_positions(iiwa, TrueRobot(np.zeros(7), link_motions=motions), sensor, q)
    np.testing.assert_allclose(turned, nominal @ spatial.rot_z(2e-3).T, atol=1e-15)


def test_truth_records_rigid_link_motions_drawn_from_their_own_seed(iiwa):
    rigid = scenario.simulate(
        small_scenario(link_errors={"translation_std": 1e-4, "rotation_std": 2e-4, "seed": 3}), iiwa
    )
    robot = scenario.robot_from_truth(rigid.truth)
    draw = np.random.default_rng(3)
    expected = np.hstack([draw.normal(0.0, 1e-4, (8, 3)), draw.normal(0.0, 2e-4, (8, 3))])
    np.testing.assert_array_equal(robot.link_motions, expected)


BAD_PLANS = [
    (
        {"held_joints": {"q1": 0.0}},
        "plan/held_joints/q1: the latin_hypercube design's inverse kinematics holds joint 3 only",
    ),
    ({"q3": "sometimes"}, "plan/q3: must be an angle"),
    ({"q3": 0.0, "held_joints": {"q3": 0.1}}, "plan/q3: joint 3 is held twice"),
    ({"held_joints": {"q9": 0.0}}, r"plan/held_joints/q9: names no joint of the robot \(q1 .. q7\)"),
    ({"design": "random_joints", "held_joints": {"q2": 3.0}}, "plan/held_joints/q2: 3 rad is outside joint 2's limits"),
    ({"q_3": 0.0}, "plan/q_3: unknown key"),
    ({"design": "random_joints"}, "plan/sets/optimization/poses: unknown key .* for design random_joints"),
]


@pytest.mark.parametrize(("plan", "message"), BAD_PLANS)
def test_bad_plan_keys_are_refused_by_name(iiwa, plan, message):
    spec = small_scenario()
    spec["plan"].update(plan)
    with pytest.raises(InputError, match=message):
        scenario.simulate(spec, iiwa)


BAD_TRUTHS = [
    ({"link_errors": {"length_std": 1e-4, "rotation_std": 1e-4}}, "truth/link_errors/length_std: unknown key"),
    ({"link_errors": {"translation_std": 1e-4, "size": 1}}, "truth/link_errors/size: unknown key"),
    ({"link_errors": {"translation_std": -1.0, "rotation_std": 1e-4}}, "truth/link_errors/translation_std"),
    ({"dh_errors": {"std": [1e-4, 1e-4, 1e-4, 1e-4]}}, r"truth/dh_errors: DH errors need a robot given by a DH table"),
    ({"link_error": {}}, "truth/link_error: unknown key"),
]


@pytest.mark.parametrize(("truth", "message"), BAD_TRUTHS)
def test_bad_truth_keys_are_refused_by_name(iiwa, truth, message):
    spec = small_scenario()
    spec["truth"].pop("link_errors")
    spec["truth"].update(truth)
    with pytest.raises(InputError, match=message):
        scenario.simulate(spec, iiwa)


def test_dh_errors_with_compliance_on_a_urdf_in_other_frames_are_refused(iiwa):
    spec = small_scenario(dh_errors={"std": [1e-4, 1e-4, 1e-4, 1e-4], "seed": 1})
    spec["robot"]["dh"] = {"convention": "standard", "rows": [[0.0, np.pi / 2, 0.36, 0.0]] * 7}
    with pytest.raises(InputError, match="truth/dh_errors: DH errors rebuild the joint frames"):
        scenario.simulate(spec, iiwa)


def test_a_six_axis_arm_needs_the_random_joints_design(ur5_dh):
    spec = small_scenario()
    spec["truth"] = {"zero_offsets_deg": [0.1] * 6}
    with pytest.raises(InputError, match="plan/design: the latin_hypercube design needs a 7-axis"):
        scenario.simulate(spec, ur5_dh)


def test_backlash_adds_half_the_play_by_the_direction_of_approach(iiwa):
    play = np.radians([0.0, 0.02, 0.0, 0.0, 0.0, 0.0, 0.0])
    robot = TrueRobot(zero_offsets=np.zeros(7), backlash=play)
    q = np.zeros((5, 7))
    q[:, 1] = [0.0, 0.3, 0.1, 0.1, 0.4]  # first reading +, up, down, still (keeps down), up
    true = true_joint_angles(iiwa, robot, q)
    np.testing.assert_allclose(true[:, 1] - q[:, 1], play[1] * np.array([1, 1, -1, -1, 1]))
    np.testing.assert_allclose(true[:, 0], 0.0)


def test_thermal_growth_lengthens_every_link_and_is_recorded(iiwa):
    out = scenario.simulate(small_scenario(link_scale=3e-4, backlash_deg=[0.0, 0.01] + [0.0] * 5), iiwa)
    assert {"link_scale", "backlash"} <= set(out.truth["effects"])
    robot = scenario.robot_from_truth(out.truth)
    assert robot.link_scale == 3e-4
    np.testing.assert_allclose(np.degrees(robot.backlash), [0.0, 0.01] + [0.0] * 5)
    grown = simulation.true_chain(iiwa, TrueRobot(zero_offsets=np.zeros(7), link_scale=3e-4))
    np.testing.assert_allclose(grown.joint_transforms[:, :3, 3], iiwa.joint_transforms[:, :3, 3] * (1 + 3e-4))
    np.testing.assert_allclose(grown.joint_transforms[:, :3, :3], iiwa.joint_transforms[:, :3, :3])


def test_random_joints_drawn_within_given_ranges_a_turn_away(ur5_dh):
    spec = small_scenario()
    spec["truth"] = {"zero_offsets_deg": [0.1] * 6}
    spec["plan"] = {
        "design": "random_joints",
        "joint_ranges": {"q1": [4.3, 5.9]},
        "seconds_per_configuration": 30,
        "sets": {"optimization": {"configurations": 10}, "validation": {"configurations": 5}},
    }
    spec["sensors"] = {name: s for name, s in spec["sensors"].items() if name == "laser_tracker"}
    q1 = scenario.simulate(spec, ur5_dh).tables["laser_tracker"]["q1"]
    assert q1.between(4.3, 5.9).all()


def test_joint_ranges_of_another_design_are_refused(iiwa):
    spec = small_scenario()
    spec["plan"]["joint_ranges"] = {"q1": [-0.5, 0.5]}
    with pytest.raises(InputError, match="plan/joint_ranges"):
        scenario.simulate(spec, iiwa)
