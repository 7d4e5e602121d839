"""`remaster import` from a ROS 2 bag: the controller's sensor_msgs/msg/JointState messages in an MCAP
file become the controller log, mapped to the robot's joints by name and matched to a sensor's CSV
export by time; every problem with the bag is an error naming it and what is wrong."""

from __future__ import annotations

import collections
import io
import struct

import numpy as np
import pandas as pd
import pytest
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_ros2.writer import Writer

from benchmarks.bench_damaged_bags import damaged
from remaster import cli, files
from remaster.campaigns import bags, folders, importer
from remaster.campaigns.simulation import Sensor, TrueRobot, looking_at, measure
from remaster.errors import InputError
from remaster.inference import fit

from ..conftest import REPO

# sensor_msgs/msg/JointState as rosbag2 records its schema: the message, then each type it uses
JOINT_STATE = "sensor_msgs/msg/JointState"
JOINT_STATE_MSGDEF = """\
std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
JOINTS = [f"joint_a{j}" for j in range(1, 8)]
START = 1_714_644_000_123_456_789  # 2024-05-02T10:00:00.123456789Z, ns
STEP = 2_000_000_000  # ns between joint states
LOG_LAG = 3_000_000  # ns from a message's header stamp to the bag's log time
MISSED = 3  # the state (0-based) the tracker has no row for
MARKER = np.array([-0.1, 0.0, 0.02])


def joint_state(stamp: int, names, positions) -> dict:
    return {
        "header": {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}, "frame_id": ""},
        "name": list(names),
        "position": [float(p) for p in positions],
        "velocity": [],
        "effort": [],
    }


def write_bag(path, messages, topic="/joint_states", datatype=JOINT_STATE, msgdef=JOINT_STATE_MSGDEF):
    """An MCAP bag with `messages` [(log time ns, message)] on `topic`, each followed by a
    std_msgs/msg/String on /rosout (another topic, to be ignored)."""
    with path.open("wb") as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef(datatype, msgdef)
        text = writer.register_msgdef("std_msgs/msg/String", "string data\n")
        for log_time, message in messages:
            writer.write_message(topic, schema, message, log_time=log_time)
            writer.write_message("/rosout", text, {"data": "moving"}, log_time=log_time + 1)
        writer.finish()
    return path


def states(q):
    """(log time, JointState) of each row of q (n, 7) rad: the names in another order than the
    robot's, a different one in every message, with the gripper's joint among them."""
    out = []
    for i, row in enumerate(q):
        order = np.random.default_rng(i).permutation(len(JOINTS) + 1)
        names = [*JOINTS, "gripper_finger"]
        values = [*row, 0.01]
        stamp = START + i * STEP
        out.append((stamp + LOG_LAG, joint_state(stamp, [names[k] for k in order], [values[k] for k in order])))
    return out


def campaign_inputs(tmp_path, iiwa, rng, n=10):
    """joints.mcap of n joint states of the iiwa and tracker.csv of the simulated tracker's
    measurements of them (mm, ISO times 40 ms after each state), but none of state MISSED and one
    row 100 s after the last; returns q (n, 7) rad and the sensor."""
    q = rng.uniform(0.6 * iiwa.lower, 0.6 * iiwa.upper, (n, 7))
    write_bag(tmp_path / "joints.mcap", states(q))
    sensor = Sensor("laser_tracker", "laser_tracker", looking_at([1.6, 0.5, 1.0], [0, 0, 0.6]), 1e-5, MARKER)
    xyz = measure(iiwa, TrueRobot(zero_offsets=np.zeros(7)), sensor, q, rng)
    seen = [i for i in range(n) if i != MISSED]
    times = [pd.Timestamp(START + i * STEP + 40_000_000, unit="ns", tz="UTC") for i in seen]
    times.append(times[-1] + pd.Timedelta(seconds=100))
    xyz_mm = 1e3 * np.vstack([xyz[seen], xyz[seen[-1]]])
    rows = [f"{t.isoformat()},{x:.17g},{y:.17g},{z:.17g}\n" for t, (x, y, z) in zip(times, xyz_mm)]
    (tmp_path / "tracker.csv").write_text("t,X,Y,Z\n" + "".join(rows), encoding="utf-8")
    return q, sensor, xyz


def write_config(tmp_path, controller=None, sensor=None):
    config = {
        "name": "bag-cell",
        "date": "2024-05-02",
        "description": "joint states from a ROS 2 bag",
        "robot": {"urdf": "data/robots/kuka_iiwa14.urdf", "base": "iiwa_link_0", "flange": "iiwa_link_ee"},
        "controller": {"bag": "joints.mcap", "topic": "/joint_states", "joints": JOINTS, **(controller or {})},
        "sensors": {
            "laser_tracker": {
                "kind": "laser_tracker",
                "marker": MARKER.tolist(),
                "noise": 1e-5,
                "file": "tracker.csv",
                "xyz": ["X", "Y", "Z"],
                "unit": "mm",
                "match": "time",
                "time": "t",
                "tolerance": 0.5,
                **(sensor or {}),
            }
        },
    }
    config = {k: v for k, v in config.items() if v is not None}
    files.write_yaml(tmp_path / "import.yaml", config)
    return tmp_path / "import.yaml"


def run_import(config, tmp_path):
    return folders.import_campaign(config, tmp_path / "raw", repo_root=REPO)


def test_joint_states_become_the_controller_log_matched_by_time(tmp_path, iiwa, rng):
    q, sensor, xyz = campaign_inputs(tmp_path, iiwa, rng)
    folder, report = run_import(write_config(tmp_path), tmp_path)
    campaign = folders.read_campaign(folder, repo_root=REPO)
    table = campaign.sensors["laser_tracker"].table
    np.testing.assert_array_equal(table[[f"q{j}" for j in range(1, 8)]].to_numpy(), q)  # rad, joint order
    stamps = pd.to_datetime([START + i * STEP for i in range(len(q))], unit="ns", utc=True)
    assert table["time"].tolist() == stamps.tolist()  # the header stamps, to the ns
    assert table["set"].eq("optimization").all() and table["pose"].tolist() == list(range(len(q)))
    assert table["solution"].eq(0).all()
    measured = np.arange(len(q)) != MISSED
    np.testing.assert_allclose(table[["x", "y", "z"]].to_numpy()[measured], xyz[measured], rtol=0, atol=1e-12)
    assert table.loc[MISSED, ["x", "y", "z"]].isna().all()

    bag, tracker = str(tmp_path / "joints.mcap"), str(tmp_path / "tracker.csv")
    assert report["controller"] == {
        "file": bag,
        "rows": len(q),
        "joint_unit": "rad",
        "topic": "/joint_states",
        "stamp": "header",
    }
    section = report["sensors"]["laser_tracker"]
    assert section["matched"] == len(q) - 1 and report["unmatched_rows"] == 1
    [unmatched] = section["unmatched"]
    assert unmatched["file"] == tracker and unmatched["line"] == len(q) + 1
    assert "no controller time within 0.5 s (nearest 100.04 s away)" in unmatched["reason"]
    assert section["not_measured"] == [
        {"file": bag, "message": MISSED + 1, "time": "2024-05-02T10:00:06.123456789+00:00"}
    ]

    registration = fit.registration_stage(campaign, "laser_tracker")
    assert registration.kabsch_rms < 3e-5
    np.testing.assert_allclose(registration.kabsch_t_nr, sensor.robot_to_sensor, atol=1e-4)


def test_the_log_time_stamps_the_states_when_asked(tmp_path, iiwa, rng):
    q, _, _ = campaign_inputs(tmp_path, iiwa, rng)
    folder, report = run_import(write_config(tmp_path, controller={"stamp": "log", "unit": "rad"}), tmp_path)
    table = folders.read_campaign(folder, repo_root=REPO).sensors["laser_tracker"].table
    logged = pd.to_datetime([START + i * STEP + LOG_LAG for i in range(len(q))], unit="ns", utc=True)
    assert table["time"].tolist() == logged.tolist() and report["controller"]["stamp"] == "log"
    assert report["sensors"]["laser_tracker"]["matched"] == len(q) - 1


def test_the_cli_imports_a_bag(tmp_path, iiwa, rng, capsys, monkeypatch):
    monkeypatch.chdir(REPO)
    campaign_inputs(tmp_path, iiwa, rng)
    config = write_config(tmp_path)
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(tmp_path / "raw")]) == 0
    assert "9 of 10 rows matched" in capsys.readouterr().out
    (tmp_path / "joints.mcap").unlink()
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(tmp_path / "raw"), "--force"]) == 2
    assert f"{tmp_path / 'joints.mcap'}: file not found" in capsys.readouterr().err


# --------------------------------------------------------------------------- the bag's errors


def import_error(tmp_path, **config) -> str:
    with pytest.raises(InputError) as error:
        run_import(write_config(tmp_path, **config), tmp_path)
    assert not (tmp_path / "raw" / "bag-cell").exists()
    return str(error.value)


def one_state(stamp=START, names=JOINTS, positions=(0.1,) * 7):
    return [(stamp + LOG_LAG, joint_state(stamp, names, positions))]


@pytest.fixture
def inputs(tmp_path, iiwa, rng):
    """A tracker export and a good bag, for each test to spoil."""
    campaign_inputs(tmp_path, iiwa, rng)
    return tmp_path


def test_a_missing_bag_or_a_folder_is_named(inputs):
    (inputs / "joints.mcap").unlink()
    assert import_error(inputs) == f"{inputs / 'joints.mcap'}: file not found (the bag named by controller/bag)"
    (inputs / "rosbag").mkdir()
    write_bag(inputs / "rosbag" / "rosbag_0.mcap", one_state())
    message = import_error(inputs, controller={"bag": "rosbag"})
    assert message.startswith(f"{inputs / 'rosbag'}: is a folder, not a bag file") and "rosbag_0.mcap" in message


def test_a_file_that_is_not_mcap_is_named(inputs):
    (inputs / "joints.mcap").write_text("time,a1\n0,0.1\n", encoding="utf-8")
    message = import_error(inputs)
    assert message.startswith(f"{inputs / 'joints.mcap'}: not a readable MCAP file: ")
    cut = write_bag(inputs / "cut.mcap", states(np.zeros((3, 7))))
    cut.write_bytes(cut.read_bytes()[:-40])  # cut off while recording: no footer
    assert "cut.mcap: not a readable MCAP file" in import_error(inputs, controller={"bag": "cut.mcap"})


def test_an_absent_topic_lists_the_bags_topics(inputs):
    message = import_error(inputs, controller={"topic": "/iiwa/joint_states"})
    assert message == (
        f"{inputs / 'joints.mcap'}: /iiwa/joint_states: no such topic in the bag; its topics: "
        "/joint_states (sensor_msgs/msg/JointState), /rosout (std_msgs/msg/String)"
    )


def test_another_message_type_on_the_topic_is_refused(inputs):
    write_bag(
        inputs / "joints.mcap", [(START, {"data": "hello"})], datatype="std_msgs/msg/String", msgdef="string data\n"
    )
    message = import_error(inputs)
    assert message == (
        f"{inputs / 'joints.mcap'}: /joint_states: carries std_msgs/msg/String messages, not sensor_msgs/msg/JointState"
    )


def test_a_message_without_one_of_the_joints_is_named(inputs):
    good = one_state()
    short = one_state(START + STEP, JOINTS[:6], (0.2,) * 6)
    write_bag(inputs / "joints.mcap", good + short)
    assert import_error(inputs) == (
        f"{inputs / 'joints.mcap'}: /joint_states: message 2 (log time 2024-05-02T10:00:02.126456789+00:00) has no "
        "joint joint_a7; its names: joint_a1, joint_a2, joint_a3, joint_a4, joint_a5, joint_a6"
    )


def test_a_joint_named_twice_is_refused(inputs):
    write_bag(inputs / "joints.mcap", one_state(names=[*JOINTS[:6], "joint_a1"]))
    message = import_error(inputs)
    assert message.startswith(f"{inputs / 'joints.mcap'}: /joint_states: message 1 (log time ")
    assert "has no joint joint_a7; its names: joint_a1, " in message
    write_bag(inputs / "joints.mcap", one_state(names=[*JOINTS, "joint_a1"], positions=(0.1,) * 8))
    assert "message 1 (log time 2024-05-02T10:00:00.126456789+00:00) has joint joint_a1 more than once" in (
        import_error(inputs)
    )


def test_two_states_at_one_time_are_refused_for_matching(inputs):
    write_bag(inputs / "joints.mcap", one_state() + one_state() + one_state(START + STEP))
    assert import_error(inputs) == (
        f"{inputs / 'joints.mcap'}: header.stamp: repeated times (matching by time needs distinct times) on "
        "messages 1, 2: '2024-05-02T10:00:00.123456789+00:00', '2024-05-02T10:00:00.123456789+00:00'"
    )


def test_positions_not_one_per_name_are_refused(inputs):
    write_bag(inputs / "joints.mcap", one_state() + one_state(START + STEP, JOINTS, (0.2,) * 6))
    message = import_error(inputs)
    assert message.startswith(f"{inputs / 'joints.mcap'}: /joint_states: message 2 (log time ")
    assert message.endswith("has 7 names but 6 positions (one per name)")


def test_a_position_that_is_not_finite_is_refused(inputs):
    positions = [0.1, 0.2, np.nan, 0.0, 0.0, 0.0, 0.0]
    write_bag(inputs / "joints.mcap", one_state() + one_state(START + STEP, JOINTS, positions))
    message = import_error(inputs)
    assert message.startswith(f"{inputs / 'joints.mcap'}: /joint_states: message 2 (log time ")
    assert message.endswith(": position not finite: joint_a3 = nan")


def test_a_bag_without_joint_states_is_refused(inputs):
    with (inputs / "joints.mcap").open("wb") as stream:  # the topic recorded, no message on it
        writer = McapWriter(stream)
        writer.start(profile="ros2")
        schema = writer.register_schema(JOINT_STATE, "ros2msg", JOINT_STATE_MSGDEF.encode())
        writer.register_channel("/joint_states", "cdr", schema)
        writer.finish()
    assert import_error(inputs) == f"{inputs / 'joints.mcap'}: /joint_states: no message on this topic in the bag"


def test_an_unset_header_stamp_points_to_the_log_time(inputs):
    write_bag(inputs / "joints.mcap", one_state(stamp=0) + one_state(START))
    message = import_error(inputs)
    assert message.startswith(f"{inputs / 'joints.mcap'}: /joint_states: header stamp 0 (never set by the publisher)")
    assert "on message 1: use stamp: log" in message


# --------------------------------------------------------------------------- the configuration's errors


@pytest.mark.parametrize(
    ("key", "value", "why"),
    [
        ("set", "phase", "every joint state is in the optimization set"),
        ("pose", "pose_id", "every joint state is its own pose"),
        ("solution", "ik_solution", "every joint state is solution 0"),
        ("key", "point", "a bag has no key column: match the sensors by time"),
        ("file", "controller.csv", "give file (a CSV log) or bag (a ROS 2 bag), not both"),
        ("time_format", "unix_s", "a setting of a CSV log"),
    ],
)
def test_keys_of_a_csv_log_are_refused_with_a_bag(inputs, key, value, why):
    message = import_error(inputs, controller={key: value})
    assert message.startswith(f"{inputs / 'import.yaml'}: controller/{key}: does not apply to a bag: {why}")


def test_a_bags_unit_is_rad_and_its_sensors_are_matched_by_time(inputs):
    message = import_error(inputs, controller={"unit": "deg"})
    assert message == (
        f"{inputs / 'import.yaml'}: controller/unit: must be rad or absent for a bag "
        "(JointState positions are in rad), got 'deg'"
    )
    message = import_error(inputs, sensor={"match": "key", "key": "t", "tolerance": None})
    assert message.startswith(f"{inputs / 'import.yaml'}: sensors/laser_tracker/match: sensor 'laser_tracker' is")
    assert "use match: time" in message
    message = import_error(inputs, sensor={"time": None})
    assert message.startswith(f"{inputs / 'import.yaml'}: sensors/laser_tracker/time: missing: the sensor's time")
    assert "topic" in import_error(inputs, controller={"topic": None})


def test_importer_names_a_bags_rows_messages():
    """The controller table of joint states counts messages, not lines, in what it says."""
    spec = importer.ControllerSpec(
        file=importer.FileSpec("j.mcap"), joints=("a",), unit="rad", time="header.stamp", bag=importer.BagSpec("/js")
    )
    states = [bags.JointState(i + 1, START + i, START + i, ("a",), (p,)) for i, p in enumerate((0.1, 0.2, 0.1))]
    export = importer.joint_state_export(states, spec, "j.mcap")
    assert export.cells["a"].tolist() == ["0.1", "0.2", "0.1"] and export.row_name == "message"
    assert str(export.fail("a", "bad", [0, 2])) == "j.mcap: a: bad on messages 1, 3: '0.1', '0.1'"


# --------------------------------------------------------------------------- a damaged bag


def bag_bytes(q, compression=CompressionType.NONE, crcs=True) -> bytes:
    """The bytes of a bag of the joint states of q (`states`), its chunks compressed or not, with
    or without the CRCs of its chunks and summary."""
    stream = io.BytesIO()
    writer = Writer(stream, compression=compression, enable_crcs=crcs)
    schema = writer.register_msgdef(JOINT_STATE, JOINT_STATE_MSGDEF)
    text = writer.register_msgdef("std_msgs/msg/String", "string data\n")
    for log_time, message in states(q):
        writer.write_message("/joint_states", schema, message, log_time=log_time)
        writer.write_message("/rosout", text, {"data": "moving"}, log_time=log_time + 1)
    writer.finish()
    return stream.getvalue()


def test_one_float_changed_in_an_uncompressed_chunk_is_refused_by_its_crc(inputs, iiwa, rng, capsys, monkeypatch):
    q = rng.uniform(0.6 * iiwa.lower, 0.6 * iiwa.upper, (10, 7))
    data = bag_bytes(q)
    value = struct.pack("<d", q[4, 2])
    assert data.count(value) == 1  # q3 of row 4, as CDR stores it (little-endian float64)
    bag = inputs / "joints.mcap"
    bag.write_bytes(data.replace(value, struct.pack("<d", q[4, 2] + 0.5)))
    message = import_error(inputs)
    assert message.startswith(f"{bag}: damaged: the CRC of its chunk at log times ")
    assert "does not match its bytes" in message
    monkeypatch.chdir(REPO)
    config = write_config(inputs)
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(inputs / "raw")]) == 2
    assert capsys.readouterr().err.startswith(f"remaster import: error: {bag}: damaged: the CRC of its chunk")
    assert not (inputs / "raw" / "bag-cell").exists()


def test_a_changed_summary_is_refused_by_its_crc(tmp_path):
    data = bag_bytes(np.zeros((3, 7)))
    at = data.index(b"/rosout", data.index(b"/rosout") + 1)  # the summary's copy of the channel
    with pytest.raises(
        InputError, match=r"^b\.mcap: damaged: the CRC of its summary section \(footer\) does not match"
    ):
        bags.read_joint_states(io.BytesIO(data[:at] + b"/rosin" + data[at + 6 :]), "/joint_states", "b.mcap")


def test_a_bag_without_crcs_is_read_with_nothing_to_check(tmp_path):
    q = np.random.default_rng(0).uniform(-1, 1, (4, 7))
    _, _, checked = bags._read_through(io.BytesIO(bag_bytes(q, crcs=False)), {"/joint_states"})
    assert checked == []
    _, _, checked = bags._read_through(io.BytesIO(bag_bytes(q)), {"/joint_states"})
    assert checked == ["chunks", "summary"]  # mcap's writers leave the data section's CRC 0 unless asked


@pytest.mark.parametrize("compression", [CompressionType.NONE, CompressionType.ZSTD], ids=["none", "zstd"])
def test_a_randomly_damaged_bag_is_read_right_or_refused_naming_it(compression):
    q = np.random.default_rng(0).uniform(-1, 1, (10, 7))
    data = bag_bytes(q, compression)
    good = bags.read_joint_states(io.BytesIO(data), "/joint_states", "good.mcap")
    rng = np.random.default_rng(2024)
    outcomes = collections.Counter()
    for _ in range(200):
        try:
            read = bags.read_joint_states(io.BytesIO(damaged(data, rng)), "/joint_states", "damaged.mcap")
        except InputError as error:  # anything else fails the test
            assert str(error).startswith("damaged.mcap: ")
            outcomes["refused"] += 1
        else:
            assert read == good  # a byte nothing reads (padding, an index, a statistic)
            outcomes["same"] += 1
    assert outcomes["refused"] > 150


def test_a_validation_window_splits_the_joint_states(tmp_path, iiwa, rng):
    q, _, _ = campaign_inputs(tmp_path, iiwa, rng)
    window = {"from": "2024-05-02T10:00:14Z", "to": "2024-05-02T12:00:20+02:00"}  # states 7, 8, 9 (10:00:14.12...)
    folder, report = run_import(write_config(tmp_path, controller={"validation": window}), tmp_path)
    table = folders.read_campaign(folder, repo_root=REPO).sensors["laser_tracker"].table
    assert report["controller"]["validation"] == {
        "from": "2024-05-02T10:00:14+00:00",
        "to": "2024-05-02T10:00:20+00:00",
    }
    assert table["set"].tolist() == ["optimization"] * 7 + ["validation"] * 3
    assert table["pose"].tolist() == [*range(7), 0, 1, 2]
