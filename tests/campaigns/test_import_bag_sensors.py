"""`remaster import` of a ROS 2 bag holding the joint states and the sensor's measurements both, in
either storage (MCAP, sqlite3): the sensor's samples drive the rows, each paired with the joint state
nearest its stamp (or interpolated while the robot stood still), the validation set a time window.
The bags are written with rosbags' writer, as rosbag2 writes them."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as BagWriter
from rosbags.typesys import Stores, get_typestore

from remaster import api, cli, files
from remaster.campaigns import folders
from remaster.campaigns.simulation import Sensor, TrueRobot, looking_at, measure
from remaster.errors import InputError

from ..conftest import REPO

TYPES = get_typestore(Stores.ROS2_HUMBLE)
JOINTS = [f"joint_a{j}" for j in range(1, 8)]
START = 1_714_644_000_000_000_000  # 2024-05-02T10:00:00Z, ns
SECOND = 1_000_000_000
DWELL = 2 * SECOND  # the robot holds pose i from START + i DWELL for 1.5 s, then moves to the next
STATE_EVERY = SECOND // 5  # joint states at 5 Hz
SAMPLE_AT = 805_000_000  # ns into a dwell the tracker samples: 5 ms from a joint state
GAP_POSE = 3  # the pose whose joint states 1.0 s and 1.2 s into its dwell are lost (a dropped stretch)
TOLERANCE = 0.02  # s
MARKER = np.array([-0.1, 0.0, 0.02])
FRAME = "tracker"
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}


def q_at(poses: np.ndarray, t: int) -> np.ndarray:
    """The joints (rad) at time t (ns): pose i held for 1.5 s, then a straight move to pose i + 1."""
    i, into = divmod(t - START, DWELL)
    i = min(int(i), len(poses) - 1)
    if into <= 1.5 * SECOND or i == len(poses) - 1:
        return poses[i]
    w = (into - 1.5 * SECOND) / (0.5 * SECOND)
    return poses[i] + w * (poses[i + 1] - poses[i])


def header(t: int, frame: str = ""):
    return TYPES.types["std_msgs/msg/Header"](
        stamp=TYPES.types["builtin_interfaces/msg/Time"](sec=t // SECOND, nanosec=t % SECOND), frame_id=frame
    )


def vector(kind: str, xyz):
    return TYPES.types[kind](*(float(v) for v in xyz))


def quaternion():
    return TYPES.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)


def measurement(msgtype: str, t: int, xyz, frame: str = FRAME):
    """One sample of the tracker's marker at xyz (m) as a message of `msgtype`."""
    m = TYPES.types
    if msgtype == "geometry_msgs/msg/PointStamped":
        return m[msgtype](header=header(t, frame), point=vector("geometry_msgs/msg/Point", xyz))
    if msgtype == "geometry_msgs/msg/PoseStamped":
        pose = m["geometry_msgs/msg/Pose"](position=vector("geometry_msgs/msg/Point", xyz), orientation=quaternion())
        return m[msgtype](header=header(t, frame), pose=pose)

    def transform(child, at):
        moved = m["geometry_msgs/msg/Transform"](
            translation=vector("geometry_msgs/msg/Vector3", at), rotation=quaternion()
        )
        return m["geometry_msgs/msg/TransformStamped"](header=header(t, frame), child_frame_id=child, transform=moved)

    if msgtype == "geometry_msgs/msg/TransformStamped":
        return transform("marker", xyz)
    # a TFMessage: the marker's transform among another body's
    return m[msgtype](transforms=[transform("tool_rack", (1.0, 2.0, 0.5)), transform("marker", xyz)])


def write_bag(folder, storage, topics):
    """A rosbag2 bag in `folder` (storage "mcap" or "sqlite3") of topics {topic: (msgtype, [(t, message)])},
    each message logged 3 ms after its stamp; returns the bag file."""
    with BagWriter(folder, version=8, storage_plugin=STORAGES[storage]) as writer:
        for topic, (msgtype, messages) in topics.items():
            connection = writer.add_connection(topic, msgtype, typestore=TYPES)
            for t, message in messages:
                writer.write(connection, t + 3_000_000, TYPES.serialize_cdr(message, msgtype))
    return next(folder.glob("*.mcap" if storage == "mcap" else "*.db3"))


def joint_state(t: int, q):
    return TYPES.types["sensor_msgs/msg/JointState"](
        header=header(t),
        name=[*reversed(JOINTS), "gripper_finger"],  # another order than the robot's
        position=np.array([*q[::-1], 0.01]),
        velocity=np.array([]),
        effort=np.array([]),
    )


def recording(iiwa, rng, n=10, msgtype="geometry_msgs/msg/PointStamped", moving_sample=True, zero_offsets=None):
    """The joint states and tracker samples of n poses: one sample per dwell (SAMPLE_AT into it), one
    more where the joint states of GAP_POSE are lost (no state within TOLERANCE, the robot still),
    and one while moving (no state within TOLERANCE, the robot moving). Returns (poses, topics,
    sample times, the tracker's sensor)."""
    poses = rng.uniform(0.6 * iiwa.lower, 0.6 * iiwa.upper, (n, 7))
    lost = (START + GAP_POSE * DWELL + 850_000_000, START + GAP_POSE * DWELL + 1_350_000_000)
    state_times = [t for t in range(START, START + n * DWELL, STATE_EVERY) if not lost[0] <= t <= lost[1]]
    states = [(t, joint_state(t, q_at(poses, t))) for t in state_times]
    samples = [START + i * DWELL + SAMPLE_AT for i in range(n)]
    samples.append(START + GAP_POSE * DWELL + 1_100_000_000)  # 300 ms from the states around it, the robot still
    if moving_sample:
        samples.append(START + 5 * DWELL + 1_700_000_000)  # 100 ms from the states around it, the robot moving
    samples.sort()
    sensor = Sensor("laser_tracker", "laser_tracker", looking_at([1.6, 0.5, 1.0], [0, 0, 0.6]), 1e-5, MARKER)
    truth = TrueRobot(zero_offsets=np.zeros(7) if zero_offsets is None else zero_offsets)
    xyz = measure(iiwa, truth, sensor, np.array([q_at(poses, t) for t in samples]), rng)
    tracker = [(t, measurement(msgtype, t, p)) for t, p in zip(samples, xyz)]
    topics = {"/joint_states": ("sensor_msgs/msg/JointState", states), "/tracker": (msgtype, tracker)}
    return poses, topics, samples, xyz


def write_config(tmp_path, bag, controller=None, sensor=None):
    config = {
        "name": "bag-cell",
        "date": "2024-05-02",
        "robot": {"urdf": "data/robots/kuka_iiwa14.urdf", "base": "iiwa_link_0", "flange": "iiwa_link_ee"},
        "controller": {"bag": str(bag.relative_to(tmp_path)), "topic": "/joint_states", "joints": JOINTS},
        "sensors": {
            "laser_tracker": {
                "kind": "laser_tracker",
                "marker": MARKER.tolist(),
                "noise": 1e-5,
                "topic": "/tracker",
                "tolerance": TOLERANCE,
                **(sensor or {}),
            }
        },
    }
    config["controller"] |= controller or {}
    files.write_yaml(tmp_path / "import.yaml", config)
    return tmp_path / "import.yaml"


def run_import(config, tmp_path):
    folder, report = folders.import_campaign(config, tmp_path / "raw", repo_root=REPO)
    return folders.read_campaign(folder, repo_root=REPO).sensors["laser_tracker"].table, report


def utc(t: int) -> pd.Timestamp:
    return pd.Timestamp(t, unit="ns", tz="UTC")


@pytest.mark.parametrize("storage", list(STORAGES))
def test_the_tracker_samples_drive_the_rows_paired_with_joint_states(tmp_path, iiwa, rng, storage):
    poses, topics, samples, xyz = recording(iiwa, rng)
    bag = write_bag(tmp_path / "bag", storage, topics)
    window = {"from": utc(START + 7 * DWELL).isoformat(), "to": "2024-05-02T10:00:20Z"}  # poses 7, 8, 9
    config = write_config(tmp_path, bag, controller={"validation": window}, sensor={"still": 1e-9})
    table, report = run_import(config, tmp_path)

    moving = START + 5 * DWELL + 1_700_000_000
    kept = [i for i, t in enumerate(samples) if t != moving]
    assert len(table) == len(samples) - 1 == len(poses) + 1
    assert table["time"].tolist() == [utc(samples[i]) for i in kept]  # the samples' stamps, to the ns
    expected_q = np.array([q_at(poses, samples[i]) for i in kept])
    np.testing.assert_array_equal(table[[f"q{j}" for j in range(1, 8)]].to_numpy(), expected_q)  # joint order
    np.testing.assert_allclose(table[["x", "y", "z"]].to_numpy(), xyz[kept], rtol=0, atol=1e-15)
    validation = table["set"] == "validation"
    assert table.loc[validation, "time"].tolist() == [utc(START + i * DWELL + SAMPLE_AT) for i in (7, 8, 9)]
    assert table.loc[validation, "pose"].tolist() == [0, 1, 2]
    assert table.loc[~validation, "pose"].tolist() == list(range(len(kept) - 3))

    section = report["sensors"]["laser_tracker"]
    assert (section["topic"], section["frame_id"], section["file"]) == ("/tracker", FRAME, str(bag))
    assert (section["rows"], section["matched"], section["excluded"]) == (len(samples), len(kept), 1)
    assert (section["interpolated"], section["validation"]) == (1, 3)
    [excluded] = section["unmatched"]
    assert excluded["message"] == samples.index(moving) + 1 and excluded["time"] == utc(moving).isoformat()
    assert "no joint state within 0.02 s (nearest 0.1 s away); the robot moved" in excluded["reason"]
    assert report["unmatched_rows"] == 1


def test_a_tracker_stamping_on_its_own_clock_is_paired_by_the_bags_log_time(tmp_path, iiwa, rng):
    """A tracker driver that stamps its samples on the tracker's clock (here 37 s ahead of the robot's)
    pairs no sample by header stamp; with stamp: log each sample's time is when the bag logged it (3 ms
    after it was taken), on the same clock as the joint states, and the rows are those of a recording
    stamped on one clock."""
    _, topics, _, _ = recording(iiwa, rng)
    one_clock = tmp_path / "one_clock"
    one_clock.mkdir()
    config = write_config(one_clock, write_bag(one_clock / "bag", "mcap", topics), sensor={"still": 1e-9})
    reference, _ = run_import(config, one_clock)
    for _, m in topics["/tracker"][1]:
        m.header.stamp.sec += 37
    bag = write_bag(tmp_path / "bag", "mcap", topics)
    message = import_error(tmp_path, bag, sensor={"still": 1e-9})
    assert "(are both stamped on one clock? stamp: log takes the bag's log time of each)" in message

    table, report = run_import(write_config(tmp_path, bag, sensor={"still": 1e-9, "stamp": "log"}), tmp_path)
    assert report["sensors"]["laser_tracker"]["stamp"] == "log"
    assert table["time"].tolist() == [t + pd.Timedelta(3, "ms") for t in reference["time"]]
    columns = [f"q{j}" for j in range(1, 8)] + ["x", "y", "z", "set", "pose"]
    pd.testing.assert_frame_equal(table[columns], reference[columns])


def test_an_unset_or_unknown_sensor_stamp_is_refused(tmp_path, iiwa, rng):
    _, topics, _, _ = recording(iiwa, rng, n=8)
    bag = write_bag(tmp_path / "bag", "mcap", topics)
    message = import_error(tmp_path, bag, sensor={"stamp": "receipt"})
    assert message.endswith("sensors/laser_tracker/stamp: must be one of header, log (got 'receipt')")
    topics["/tracker"][1][0][1].header.stamp.sec = 0
    topics["/tracker"][1][0][1].header.stamp.nanosec = 0
    bag = write_bag(tmp_path / "unset", "mcap", topics)
    message = import_error(tmp_path, bag)
    assert message.endswith(
        "header stamp 0 (never set by the publisher) on message 1: use sensors/laser_tracker/stamp: log to take "
        "the bag's log time"
    )
    table, report = run_import(write_config(tmp_path, bag, sensor={"stamp": "log", "still": 1e-9}), tmp_path)
    assert (len(table), report["sensors"]["laser_tracker"]["stamp"]) == (9, "log")  # but the moving sample


def test_without_still_a_sample_far_from_every_joint_state_is_excluded(tmp_path, iiwa, rng):
    poses, topics, samples, _ = recording(iiwa, rng, moving_sample=False)
    bag = write_bag(tmp_path / "bag", "sqlite3", topics)
    table, report = run_import(write_config(tmp_path, bag), tmp_path)
    assert len(table) == len(poses) and table["set"].eq("optimization").all()
    [excluded] = report["sensors"]["laser_tracker"]["unmatched"]
    assert excluded["reason"] == "no joint state within 0.02 s (nearest 0.3 s away)"


@pytest.mark.parametrize(
    "msgtype, sensor",
    [
        ("geometry_msgs/msg/PoseStamped", {}),
        ("geometry_msgs/msg/TransformStamped", {}),
        ("tf2_msgs/msg/TFMessage", {"child_frame": "marker"}),
    ],
    ids=["pose", "transform", "tf"],
)
def test_poses_and_transforms_give_their_position(tmp_path, iiwa, rng, msgtype, sensor):
    poses, topics, samples, xyz = recording(iiwa, rng, msgtype=msgtype, moving_sample=False)
    bag = write_bag(tmp_path / "bag", "mcap", topics)
    table, report = run_import(write_config(tmp_path, bag, sensor={"still": 1e-9, **sensor}), tmp_path)
    np.testing.assert_allclose(table[["x", "y", "z"]].to_numpy(), xyz, rtol=0, atol=1e-15)
    assert report["sensors"]["laser_tracker"]["frame_id"] == FRAME


# --------------------------------------------------------------------------- bad input


def import_error(tmp_path, bag, **config) -> str:
    with pytest.raises(InputError) as error:
        run_import(write_config(tmp_path, bag, **config), tmp_path)
    assert not (tmp_path / "raw" / "bag-cell").exists()
    return str(error.value)


@pytest.mark.parametrize("storage", list(STORAGES))
def test_a_sensor_topic_missing_from_the_bag_is_named(tmp_path, iiwa, rng, storage):
    _, topics, _, _ = recording(iiwa, rng, n=3)
    bag = write_bag(tmp_path / "bag", storage, topics)
    message = import_error(tmp_path, bag, sensor={"topic": "/vicon/marker"})
    assert message.startswith(f"{bag}: /vicon/marker: no such topic in the bag; its topics: ")
    assert "/tracker (geometry_msgs/msg/PointStamped)" in message


@pytest.mark.parametrize("storage", list(STORAGES))
def test_a_sensor_topic_of_another_message_type_is_refused(tmp_path, iiwa, rng, storage):
    _, topics, _, _ = recording(iiwa, rng, n=3)
    topics["/rosout"] = ("std_msgs/msg/String", [(START, TYPES.types["std_msgs/msg/String"](data="moving"))])
    bag = write_bag(tmp_path / "bag", storage, topics)
    message = import_error(tmp_path, bag, sensor={"topic": "/rosout"})
    assert message.startswith(
        f"{bag}: /rosout: carries std_msgs/msg/String messages, not geometry_msgs/msg/PointStamped"
    )
    message = import_error(tmp_path, bag, sensor={"topic": "/joint_states"})
    assert message.endswith("sensors/laser_tracker/topic: is the controller's joint-state topic too")


def test_no_sample_paired_within_the_tolerance_is_refused(tmp_path, iiwa, rng):
    _, topics, _, _ = recording(iiwa, rng, n=3)
    msgtype, samples = topics["/tracker"]
    topics["/tracker"] = (msgtype, [(t + 60 * SECOND, m) for t, m in samples])  # on another clock, a minute on
    for _, m in topics["/tracker"][1]:
        m.header.stamp.sec += 60
    bag = write_bag(tmp_path / "bag", "mcap", topics)
    message = import_error(tmp_path, bag)
    assert message.startswith(
        f"{bag}: /tracker: no sample has a joint state (controller/topic /joint_states) within "
        "sensors/laser_tracker/tolerance 0.02 s; the first: no joint state within 0.02 s (nearest "
    )


def test_positions_in_two_frames_are_refused(tmp_path, iiwa, rng):
    _, topics, _, _ = recording(iiwa, rng, n=3)
    topics["/tracker"][1][1][1].header.frame_id = "world"
    bag = write_bag(tmp_path / "bag", "sqlite3", topics)
    message = import_error(tmp_path, bag)
    assert (
        message
        == f"{bag}: /tracker: positions in more than one frame: 'tracker' on messages 1, 3, 4, 5; 'world' on message 2"
    )


def test_settings_of_a_csv_export_are_refused_on_a_sensor_topic(tmp_path, iiwa, rng):
    _, topics, _, _ = recording(iiwa, rng, n=3)
    bag = write_bag(tmp_path / "bag", "mcap", topics)
    message = import_error(tmp_path, bag, sensor={"unit": "mm"})
    assert message.endswith(
        "sensors/laser_tracker/unit: does not apply to a sensor topic: a message's position is in m (ROS's unit)"
    )
    message = import_error(
        tmp_path, bag, controller={"validation": {"from": "yesterday", "to": "2024-05-02T10:00:20Z"}}
    )
    assert "controller/validation/from: must be an ISO 8601 time" in message


def test_a_damaged_sqlite3_bag_is_named(tmp_path, iiwa, rng):
    _, topics, _, _ = recording(iiwa, rng, n=3)
    bag = write_bag(tmp_path / "bag", "sqlite3", topics)
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 2])  # cut off: a bad copy
    message = import_error(tmp_path, bag)
    assert message.startswith(f"{bag}: not a readable sqlite3 bag: ")
    bag.write_bytes(data[:100] + bytes(len(data) - 100))  # all but its header zeroed
    assert import_error(tmp_path, bag).startswith(f"{bag}: not a readable sqlite3 bag: ")


@pytest.mark.slow
def test_a_bag_of_either_storage_imported_calibrates_end_to_end(tmp_path, iiwa, rng):
    """40 poses recorded with zero-offsets of 0.02 deg, the last 10 the validation window, written as
    an MCAP and as a sqlite3 bag: both import into the same campaign, which calibrates, the fit lowers
    the validation set's error and the acceptance test runs on it."""
    truth = np.deg2rad([0.02, -0.02, 0.01, 0.02, -0.01, 0.02, 0.01])
    _, topics, _, _ = recording(iiwa, rng, n=40, moving_sample=False, zero_offsets=truth)
    window = {"from": utc(START + 30 * DWELL).isoformat(), "to": utc(START + 40 * DWELL).isoformat()}
    tables = {}
    for storage in STORAGES:
        (tmp_path / storage).mkdir()
        bag = write_bag(tmp_path / storage / "bag", storage, topics)
        config = write_config(tmp_path / storage, bag, controller={"validation": window}, sensor={"still": 1e-9})
        folder, report = folders.import_campaign(config, tmp_path / storage / "raw", repo_root=REPO)
        assert report["sensors"]["laser_tracker"]["validation"] == 10
        tables[storage] = folders.read_campaign(folder, repo_root=REPO).sensors["laser_tracker"].table
    pd.testing.assert_frame_equal(tables["mcap"], tables["sqlite3"])
    quick = {
        "loop_closure": {"residual_gp": {"enabled": False}},
        "accuracy": {"draws": 200, "random_configurations": 100},
        "acceptance": {"draws": 200},
    }
    calibration = api.calibrate(folders.read_campaign(folder, repo_root=REPO), "laser_tracker", quick, seed=0)
    # the zero-offsets the data determine, as simulated (the iiwa's first joint is held: no frame tells it
    # from the registration's rotation about the base's axis)
    summary = calibration.summary
    estimated = [j for j in range(7) if summary.loc[f"zero_offsets.q{j + 1}", "status"] == "estimated"]
    assert len(estimated) >= 5
    fitted = summary.loc[[f"zero_offsets.q{j + 1}" for j in estimated], "mean"].to_numpy(dtype=float)
    np.testing.assert_allclose(fitted, truth[estimated], atol=np.deg2rad(0.003))
    # the validation window's 10 rows: the error after calibration at the sensor's noise (10 um per axis)
    assert calibration.loop.report.validation_rmse_after_mm < 0.03
    assert calibration.verdict in ("pass", "fail")  # tested on the validation window's rows


def test_a_full_pose_probe_takes_the_poses_orientation(tmp_path, iiwa, rng):
    _, topics, _, _ = recording(iiwa, rng, n=6, msgtype="geometry_msgs/msg/PoseStamped", moving_sample=False)
    half_turn = np.sqrt(0.5)  # 90 deg about z: w, z = cos 45 deg, sin 45 deg
    for _, m in topics["/tracker"][1]:
        m.pose.orientation.w, m.pose.orientation.z = half_turn, half_turn
    bag = write_bag(tmp_path / "bag", "mcap", topics)
    probe = {"orientation_noise": 1e-4, "probe_rotation": [0.0, 0.0, 0.0], "still": 1e-9}
    table, _ = run_import(write_config(tmp_path, bag, sensor=probe), tmp_path)
    np.testing.assert_allclose(table[["rx", "ry", "rz"]].to_numpy(), [[0.0, 0.0, np.pi / 2]] * len(table), atol=1e-12)
    _, topics, _, _ = recording(iiwa, rng, n=3, moving_sample=False)  # points: no orientation
    (tmp_path / "points").mkdir()
    bag = write_bag(tmp_path / "points" / "bag", "mcap", topics)
    message = import_error(tmp_path / "points", bag, sensor=probe)
    assert message.startswith(
        f"{bag}: /tracker: points without an orientation on messages 1, 2, 3, 4: a full-pose probe"
    )


def test_the_cli_imports_a_bag_with_its_sensor_topic(tmp_path, iiwa, rng, capsys, monkeypatch):
    monkeypatch.chdir(REPO)
    _, topics, samples, _ = recording(iiwa, rng, n=5)
    bag = write_bag(tmp_path / "bag", "sqlite3", topics)
    config = write_config(tmp_path, bag)
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(tmp_path / "raw")]) == 0
    assert f"5 of {len(samples)} samples paired with a joint state" in capsys.readouterr().out
    config = write_config(tmp_path, bag, sensor={"topic": "/vicon/marker"})
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(tmp_path / "raw"), "--force"]) == 2
    assert f"{bag}: /vicon/marker: no such topic in the bag" in capsys.readouterr().err


def test_a_second_bag_is_the_validation_set(tmp_path, iiwa, rng):
    poses, topics, samples, xyz = recording(iiwa, rng, n=8, moving_sample=False)
    bag = write_bag(tmp_path / "bag", "sqlite3", topics)
    second_poses, second_topics, second_samples, second_xyz = recording(iiwa, rng, n=4, moving_sample=False)
    second = write_bag(tmp_path / "validation", "mcap", second_topics)  # another storage, another day's poses
    config = write_config(tmp_path, bag, controller={"validation": {"bag": str(second.relative_to(tmp_path))}})
    table, report = run_import(config, tmp_path)
    optimization, validation = table["set"] == "optimization", table["set"] == "validation"
    q = [f"q{j}" for j in range(1, 8)]
    np.testing.assert_array_equal(table.loc[optimization, q].to_numpy(), poses)  # the gap sample: no still
    np.testing.assert_array_equal(table.loc[validation, q].to_numpy(), second_poses)
    np.testing.assert_allclose(table.loc[validation, ["x", "y", "z"]].to_numpy(), second_xyz[:4], atol=1e-15)
    assert table.loc[validation, "pose"].tolist() == [0, 1, 2, 3]
    assert report["validation_bag"]["controller"]["file"] == str(second)
    assert report["validation_bag"]["sensors"]["laser_tracker"]["validation"] == 4
    assert report["unmatched_rows"] == 2  # each bag's sample while the joint states were lost


def test_a_validation_bag_missing_or_with_a_csv_sensor_is_refused(tmp_path, iiwa, rng):
    _, topics, _, _ = recording(iiwa, rng, n=3)
    bag = write_bag(tmp_path / "bag", "mcap", topics)
    message = import_error(tmp_path, bag, controller={"validation": {"bag": "nowhere.mcap"}})
    assert message == f"{tmp_path / 'nowhere.mcap'}: file not found (the bag named by controller/validation/bag)"
    csv = {"topic": None, "file": "tracker.csv", "unit": "m", "match": "time", "time": "t"}
    message = import_error(tmp_path, bag, controller={"validation": {"bag": "bag/bag.mcap"}}, sensor=csv)
    assert message.endswith(
        "sensors/laser_tracker/file: a CSV export with a validation bag (controller/validation/bag): "
        "the validation bag holds the sensors' topics, so name this sensor's topic"
    )
