"""The campaign reader: every check names the file, the key or column, and the rows."""

from __future__ import annotations

import datetime as dt
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from remaster.campaigns.campaign import SETS, validate_metadata, validate_sensor_table
from remaster.campaigns.folders import read_campaign, write_campaign
from remaster.campaigns.robot_model import load_chain, robot_section
from remaster.errors import InputError, KinematicsError
from remaster.files import read_yaml, write_json
from remaster.robot.kinematics import max_chain_difference

REPO = Path(__file__).resolve().parents[2]
IIWA_URDF = REPO / "data" / "robots" / "kuka_iiwa14.urdf"
IIWA_ROBOT = {"urdf": str(IIWA_URDF), "base": "iiwa_link_0", "flange": "iiwa_link_ee"}
SENSOR = "laser_tracker"

# A 3-joint arm, as standard DH rows [a, alpha, d, theta] and as the equivalent URDF.
SMALL_DH = {
    "convention": "standard",
    "rows": [[0.0, math.pi / 2, 0.3, 0.0], [0.4, 0.0, 0.0, 0.0], [0.2, 0.0, 0.0, 0.0]],
}
SMALL_URDF = f"""<?xml version="1.0"?>
<robot name="small">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.3" rpy="{math.pi / 2!r} 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="flange" type="fixed"><parent link="l3"/><child link="tool"/><origin xyz="0.2 0 0"/></joint>
</robot>
"""


def sensor_table(n_joints: int = 7, n_optimization: int = 6, n_validation: int = 3, seed: int = 0) -> pd.DataFrame:
    """A valid table: two IK solutions per optimization pose, joints within +-1 rad, positions ~1 m,
    a UTC time column and an extra numeric column."""
    rng = np.random.default_rng(seed)
    n = n_optimization + n_validation
    table = pd.DataFrame(
        {
            "set": ["optimization"] * n_optimization + ["validation"] * n_validation,
            "pose": np.r_[np.arange(n_optimization) // 2, np.arange(n_validation)].astype(np.int64),
            "solution": np.r_[np.arange(n_optimization) % 2, np.zeros(n_validation)].astype(np.int64),
        }
    )
    for j, column in enumerate(rng.uniform(-1.0, 1.0, (n_joints, n))):
        table[f"q{j + 1}"] = column
    for axis, column in zip("xyz", rng.uniform(-1.5, 1.5, (3, n))):
        table[axis] = column
    table["time"] = pd.date_range("2018-06-12 10:00", periods=n, freq="min", tz="UTC")
    table["temperature"] = rng.uniform(20.0, 25.0, n)
    return table


def metadata(name: str = "demo", robot: dict | None = None) -> dict:
    return {
        "name": name,
        "date": dt.date(2018, 6, 12),
        "description": "test campaign",
        "robot": dict(IIWA_ROBOT) if robot is None else robot,
        "sensors": {SENSOR: {"kind": "laser_tracker", "marker": [0.0, 0.0, 0.05], "noise": 3e-5}},
    }


def make_campaign(root: Path, meta: dict | None = None, tables: dict | None = None, name: str = "demo") -> Path:
    """Write a campaign folder root/name; a valid iiwa campaign unless told otherwise."""
    folder = root / name
    write_campaign(
        folder, metadata(name) if meta is None else meta, {SENSOR: sensor_table()} if tables is None else tables
    )
    return folder


def read_error(folder: Path, error: type[InputError] = InputError) -> InputError:
    with pytest.raises(error) as info:
        read_campaign(folder, repo_root=REPO)
    return info.value


# --------------------------------------------------------------------------- valid campaigns


def test_valid_campaign_round_trips(tmp_path):
    table = sensor_table()
    campaign = read_campaign(make_campaign(tmp_path, tables={SENSOR: table}), repo_root=REPO)
    assert (campaign.name, campaign.date, campaign.description) == ("demo", dt.date(2018, 6, 12), "test campaign")
    assert campaign.chain.n_joints == campaign.n_joints == 7
    sensor = campaign.sensors[SENSOR]
    assert (sensor.name, sensor.kind, sensor.noise) == (SENSOR, "laser_tracker", 3e-5)
    np.testing.assert_array_equal(sensor.marker, [0.0, 0.0, 0.05])
    assert sensor.joint_columns == tuple(f"q{j}" for j in range(1, 8))
    pd.testing.assert_frame_equal(sensor.table, table)  # every column, in stored order, untouched
    assert sensor.q().shape == (9, 7) and sensor.positions().shape == (9, 3)
    np.testing.assert_array_equal(sensor.q("validation"), table.loc[6:, sensor.joint_columns].to_numpy())
    np.testing.assert_array_equal(sensor.positions("optimization"), table.loc[:5, ["x", "y", "z"]].to_numpy())
    assert sensor.measured_mask.all() and sensor.n_missing == 0
    with pytest.raises(ValueError):
        sensor.q("test")


def test_validation_rows_that_copy_optimization_rows_are_found(tmp_path):
    """A validation row whose joints and position equal an optimization row's is a copy; the same
    configuration measured again (its position differs by the sensor's noise) is not."""
    table = sensor_table(n_validation=4)
    columns = [f"q{j}" for j in range(1, 8)] + ["x", "y", "z"]
    table.loc[7, columns] = table.loc[2, columns].to_numpy()
    table.loc[9, columns] = table.loc[4, columns].to_numpy()
    table.loc[8, columns] = table.loc[3, columns].to_numpy()
    table.loc[8, "x"] += 3e-5  # measured again: not a copy
    sensor = read_campaign(make_campaign(tmp_path, tables={SENSOR: table}), repo_root=REPO).sensors[SENSOR]
    np.testing.assert_array_equal(sensor.validation_copies(), [7, 9])
    assert (
        len(read_campaign(make_campaign(tmp_path, name="clean"), repo_root=REPO).sensors[SENSOR].validation_copies())
        == 0
    )


def test_write_campaign_is_deterministic(tmp_path):
    first = make_campaign(tmp_path / "a")
    second = make_campaign(tmp_path / "b")
    for file in ("campaign.yaml", f"{SENSOR}.parquet"):
        assert (first / file).read_bytes() == (second / file).read_bytes()
    campaign = read_campaign(first, repo_root=REPO)
    rewritten = write_campaign(
        tmp_path / "c" / "demo", read_yaml(first / "campaign.yaml"), {n: s.table for n, s in campaign.sensors.items()}
    )
    assert (rewritten / f"{SENSOR}.parquet").read_bytes() == (first / f"{SENSOR}.parquet").read_bytes()


def test_write_json_is_sorted_and_deterministic(tmp_path):
    data = {"b": np.float64(1.5), "a": np.arange(3), "date": dt.date(2018, 6, 12)}
    path = write_json(tmp_path / "out.json", data)
    assert (
        path.read_text()
        == json.dumps({"a": [0, 1, 2], "b": 1.5, "date": "2018-06-12"}, sort_keys=True, indent=2) + "\n"
    )


def test_set_column_may_be_object_string_or_categorical(tmp_path):
    for dtype in (object, "string", pd.CategoricalDtype(SETS)):
        table = sensor_table()
        table["set"] = table["set"].astype(dtype)
        folder = make_campaign(tmp_path / str(dtype), tables={SENSOR: table})
        assert len(read_campaign(folder, repo_root=REPO).sensors[SENSOR].q("optimization")) == 6


def test_naive_time_is_taken_as_utc(tmp_path):
    table = sensor_table()
    table["time"] = table["time"].dt.tz_localize(None)
    sensor = read_campaign(make_campaign(tmp_path, tables={SENSOR: table}), repo_root=REPO).sensors[SENSOR]
    assert str(sensor.table["time"].dt.tz) == "UTC"
    assert sensor.table["time"].iloc[0] == pd.Timestamp("2018-06-12 10:00", tz="UTC")


def test_unseen_markers_are_kept_and_counted(tmp_path, caplog):
    table = sensor_table()
    table.loc[[2, 7], ["x", "y", "z"]] = np.nan
    with caplog.at_level("INFO", logger="remaster.campaigns.folders"):
        sensor = read_campaign(make_campaign(tmp_path, tables={SENSOR: table}), repo_root=REPO).sensors[SENSOR]
    assert len(sensor.table) == 9 and sensor.n_missing == 2
    assert sensor.missing_rows.tolist() == [2, 7]
    assert sensor.measured_mask.tolist() == [i not in (2, 7) for i in range(9)]
    assert np.isnan(sensor.positions()[[2, 7]]).all()
    assert "rows 2, 7" in caplog.text


@pytest.mark.parametrize("urdf_place", ["campaign folder", "repository root", "shared robots"])
def test_urdf_is_found_in_folder_then_repo_root_then_shared_robots(tmp_path, urdf_place):
    repo = tmp_path / "repo"
    urdf = {"campaign folder": "iiwa.urdf", "repository root": "models/iiwa.urdf", "shared robots": "kuka_iiwa14.urdf"}[
        urdf_place
    ]
    target = {
        "campaign folder": repo / "demo" / urdf,
        "repository root": repo / urdf,
        "shared robots": repo / "data" / "robots" / urdf,
    }[urdf_place]
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(IIWA_URDF, target)
    folder = make_campaign(repo, metadata(robot={**IIWA_ROBOT, "urdf": urdf}))
    assert read_campaign(folder, repo_root=repo).chain.n_joints == 7


def test_dh_only_and_agreeing_urdf_and_dh(tmp_path):
    dh_only = make_campaign(tmp_path / "a", metadata(robot={"dh": SMALL_DH}), {SENSOR: sensor_table(3)})
    dh_chain = read_campaign(dh_only).chain
    assert dh_chain.n_joints == 3

    both = make_campaign(
        tmp_path / "b",
        metadata(robot={"urdf": "small.urdf", "base": "base", "flange": "tool", "dh": SMALL_DH}),
        {SENSOR: sensor_table(3)},
    )
    (both / "small.urdf").write_text(SMALL_URDF)
    campaign = read_campaign(both, repo_root=tmp_path)
    assert campaign.chain.joint_names == ("j1", "j2", "j3")  # the URDF chain is the one kept
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (20, 3))
    assert max_chain_difference(campaign.chain, dh_chain, q) < 1e-12


def test_a_stated_mpe_is_read_in_metres(tmp_path):
    """sensors/<name>/mpe: the instrument's maximum permissible error (m), optional; None without it."""
    meta = metadata()
    meta["sensors"][SENSOR]["mpe"] = 2.5e-5
    campaign = read_campaign(make_campaign(tmp_path, meta), repo_root=REPO)
    assert campaign.sensors[SENSOR].mpe == 2.5e-5
    assert validate_metadata(metadata(), source="campaign.yaml")["sensors"][SENSOR]["mpe"] is None


def test_validation_needs_no_files():
    meta = validate_metadata(metadata(), source="campaign.yaml")
    assert meta["date"] == dt.date(2018, 6, 12) and meta["sensors"][SENSOR]["noise"] == 3e-5
    table = sensor_table().set_index(np.arange(100, 109))
    checked = validate_sensor_table(table, 7, SENSOR, source="memory")
    assert checked.index.tolist() == list(range(9))
    with pytest.raises(InputError, match=r"memory: q8"):
        validate_sensor_table(sensor_table(8), 7, SENSOR, source="memory")


# --------------------------------------------------------------------------- campaign.yaml


def drop(key):
    return lambda meta: meta.pop(key)


def set_key(path, value):
    """Mutation setting meta[path[0]][path[1]]... = value."""

    def mutate(meta):
        section = meta
        for key in path[:-1]:
            section = section[key]
        section[path[-1]] = value

    return mutate


METADATA_ERRORS = {
    "missing name": (drop("name"), "name", InputError),
    "missing date": (drop("date"), "date", InputError),
    "missing robot": (drop("robot"), "robot", InputError),
    "missing sensors": (drop("sensors"), "sensors", InputError),
    "unknown key": (set_key(["operator"], "me"), "operator", InputError),
    "date not ISO": (set_key(["date"], "12.06.2018"), "date", InputError),
    "date impossible": (set_key(["date"], "2018-13-01"), "date", InputError),
    "date-time": (set_key(["date"], dt.datetime(2018, 6, 12, 10)), "date", InputError),
    "robot without model": (set_key(["robot"], {}), "robot", KinematicsError),
    "robot unknown key": (set_key(["robot", "tool"], "x"), "robot", KinematicsError),
    "urdf missing": (set_key(["robot", "urdf"], "no_such_robot.urdf"), "robot/urdf", KinematicsError),
    "base not in urdf": (set_key(["robot", "base"], "world"), "robot/base", KinematicsError),
    "flange not in urdf": (set_key(["robot", "flange"], "tool0"), "robot/flange", KinematicsError),
    "dh convention": (
        set_key(["robot"], {"dh": {**SMALL_DH, "convention": "craig"}}),
        "robot/dh/convention",
        KinematicsError,
    ),
    "dh flange": (
        set_key(["robot"], {"dh": {**SMALL_DH, "flange": [[2, 0, 0, 0]] * 4}}),
        "robot/dh/flange",
        KinematicsError,
    ),
    "unknown kind": (set_key(["sensors", SENSOR, "kind"], "camera"), f"sensors/{SENSOR}/kind", InputError),
    "marker two numbers": (set_key(["sensors", SENSOR, "marker"], [0.0, 0.1]), f"sensors/{SENSOR}/marker", InputError),
    "marker nan": (
        set_key(["sensors", SENSOR, "marker"], [0.0, float("nan"), 0.1]),
        f"sensors/{SENSOR}/marker",
        InputError,
    ),
    "marker text": (set_key(["sensors", SENSOR, "marker"], ["a", 0.0, 0.1]), f"sensors/{SENSOR}/marker", InputError),
    "noise zero": (set_key(["sensors", SENSOR, "noise"], 0.0), f"sensors/{SENSOR}/noise", InputError),
    "noise negative": (set_key(["sensors", SENSOR, "noise"], -1e-5), f"sensors/{SENSOR}/noise", InputError),
    "mpe zero": (set_key(["sensors", SENSOR, "mpe"], 0.0), f"sensors/{SENSOR}/mpe", InputError),
    "mpe text": (set_key(["sensors", SENSOR, "mpe"], "15 um"), f"sensors/{SENSOR}/mpe", InputError),
}


@pytest.mark.parametrize("case", METADATA_ERRORS)
def test_metadata_errors_name_file_and_key(tmp_path, case):
    mutate, key, error = METADATA_ERRORS[case]
    meta = metadata()
    mutate(meta)
    problem = read_error(make_campaign(tmp_path, meta), error)
    assert problem.file.endswith("campaign.yaml") and problem.key.startswith(key.split("/")[0])
    assert f"campaign.yaml: {key}" in str(problem)


def test_base_not_in_urdf_names_the_urdf(tmp_path):
    problem = read_error(make_campaign(tmp_path, metadata(robot={**IIWA_ROBOT, "base": "world"})), KinematicsError)
    assert "'world'" in str(problem) and "kuka_iiwa14.urdf" in str(problem)


def test_name_must_equal_folder(tmp_path):
    folder = make_campaign(tmp_path, metadata("other"), name="demo")
    problem = read_error(folder)
    assert "campaign.yaml: name" in str(problem) and "'other'" in str(problem) and "'demo'" in str(problem)


def test_malformed_dh_rows_are_named(tmp_path):
    dh = {**SMALL_DH, "rows": [SMALL_DH["rows"][0], [0.4, 0.0, 0.0], SMALL_DH["rows"][2], ["a", 0, 0, 0]]}
    problem = read_error(
        make_campaign(tmp_path, metadata(robot={"dh": dh}), {SENSOR: sensor_table(3)}), KinematicsError
    )
    assert "campaign.yaml: robot/dh/rows" in str(problem) and problem.rows == [1, 3]
    assert "rows 1, 3" in str(problem)


def test_disagreeing_urdf_and_dh(tmp_path):
    dh = {**SMALL_DH, "rows": [SMALL_DH["rows"][0], [0.401, 0.0, 0.0, 0.0], SMALL_DH["rows"][2]]}
    folder = make_campaign(tmp_path, metadata(robot={"urdf": "small.urdf", "dh": dh}), {SENSOR: sensor_table(3)})
    (folder / "small.urdf").write_text(SMALL_URDF)
    problem = read_error(folder, KinematicsError)
    assert "campaign.yaml: robot:" in str(problem) and "different chains" in str(problem)
    with pytest.raises(KinematicsError, match="robot: urdf and dh describe different robots"):
        load_chain({"urdf": "small.urdf", "dh": {**SMALL_DH, "rows": SMALL_DH["rows"][:2]}}, folder)


def test_sensor_without_parquet(tmp_path):
    folder = make_campaign(tmp_path)
    (folder / f"{SENSOR}.parquet").unlink()
    problem = read_error(folder)
    assert f"campaign.yaml: sensors/{SENSOR}" in str(problem) and f"{SENSOR}.parquet" in str(problem)


def test_parquet_without_sensor(tmp_path):
    folder = make_campaign(tmp_path, tables={SENSOR: sensor_table(), "mocap": sensor_table()})
    problem = read_error(folder)
    assert "mocap.parquet: sensors" in str(problem) and "'mocap'" in str(problem)


# --------------------------------------------------------------------------- <sensor>.parquet


def with_values(columns, rows, value):
    def mutate(table):
        table.loc[rows, columns] = value
        return table

    return mutate


def retyped(column, dtype):
    return lambda table: table.assign(**{column: table[column].astype(dtype)})


TABLE_ERRORS = {
    # case: (mutation, column(s) named, rows named or None, words in the message)
    "missing pose": (lambda t: t.drop(columns="pose"), "pose", None, "missing column"),
    "missing q7": (lambda t: t.drop(columns="q7"), "q7", None, "missing column"),
    "missing z": (lambda t: t.drop(columns="z"), "z", None, "missing column"),
    "extra joint q8": (lambda t: t.assign(q8=0.0), "q8", None, "7 joints"),
    "joint q0": (lambda t: t.assign(q0=0.0), "q0", None, "7 joints"),
    "pose float": (retyped("pose", float), "pose", None, "integer"),
    "solution text": (retyped("solution", str), "solution", None, "integer"),
    "joint integer": (lambda t: t.assign(q3=1), "q3", None, "float"),
    "x text": (retyped("x", str), "x", None, "float"),
    "x float16": (retyped("x", np.float16), "x", None, "has dtype float16: float16 keeps about 3 significant digits"),
    "joint float32": (retyped("q2", np.float32), "q2", None, "has dtype float32: float32 keeps about 6 significant"),
    "set numbers": (lambda t: t.assign(set=1), "set", None, "strings"),
    "time text": (retyped("time", str), "time", None, "timestamp"),
    "extra column text": (lambda t: t.assign(operator="me"), "operator", None, "numeric"),
    "negative pose": (with_values("pose", [4], -1), "pose", [4], "negative"),
    "unknown set": (with_values("set", [1, 7], "test"), "set", [1, 7], "'test'"),
    "duplicate rows": (with_values(["pose", "solution"], [3], [1, 0]), "set, pose, solution", [2, 3], "duplicate"),
    "joint nan": (with_values("q2", [5], np.nan), "q2", [5], "non-finite"),
    "joint inf": (with_values(["q1", "q6"], [0, 8], np.inf), "q1, q6", [0, 8], "non-finite"),
    "position inf": (with_values("y", [6], -np.inf), "x, y, z", [6], "infinite"),
    "partial nan": (with_values("z", [1, 4], np.nan), "x, y, z", [1, 4], "not all"),
    "millimetres": (
        lambda t: t.assign(x=t.x * 1e3, y=t.y * 1e3, z=t.z * 1e3 + 2e3),
        "x, y, z",
        list(range(9)),
        "looks like millimetres",
    ),
    "one far row": (with_values("x", [3], 25.0), "x, y, z", [3], "looks like millimetres"),
    "empty table": (lambda t: t.iloc[:0], None, None, "no rows"),
    "no optimization rows": (lambda t: t.iloc[6:], "set", None, "no optimization rows"),
}


@pytest.mark.parametrize("case", TABLE_ERRORS)
def test_table_errors_name_file_column_and_rows(tmp_path, case):
    mutate, column, rows, words = TABLE_ERRORS[case]
    problem = read_error(make_campaign(tmp_path, tables={SENSOR: mutate(sensor_table())}))
    message = str(problem)
    assert message.startswith(str(tmp_path / "demo" / f"{SENSOR}.parquet"))
    if column is not None:
        assert problem.key == column and f".parquet: {column}: " in message
    assert problem.rows == rows
    if rows:
        assert message.endswith(f"({'row' if len(rows) == 1 else 'rows'} {', '.join(map(str, rows))})")
    assert words in message


def test_median_norm_beyond_limit_looks_like_millimetres():
    table = sensor_table()
    table[["x", "y", "z"]] = [15.0, 15.0, 0.0]  # no coordinate beyond 20 m, every norm beyond it
    with pytest.raises(InputError, match="looks like millimetres") as info:
        validate_sensor_table(table, 7, SENSOR, source="memory")
    assert info.value.rows == list(range(9))


def test_a_campaign_too_large_for_a_jobs_memory_is_refused_before_any_fit(tmp_path):
    """The estimate grows with the rows of the largest sensor; a campaign over the limit is refused
    with its name, its rows, the estimate and the setting to change; one under it records the
    estimate in its summary."""
    from remaster.campaigns import campaign as campaigns
    from remaster.campaigns import capacity

    # the theoretical accuracy's draw x configuration pairs, then a few kB a row
    assert capacity.peak_estimate(10_000, draws=200) == pytest.approx(0.5e9 + 16 * 2_000_000 + 1.5e3 * 10_000)
    assert capacity.peak_estimate(1_000_000) == pytest.approx(0.5e9 + 16 * capacity.THEORETICAL_PAIRS + 1.5e3 * 1e6)
    assert 2.8e9 < capacity.peak_estimate(100_000) < 3.5e9  # the 100,000-row accuracy job measured 2.8 GB
    assert 3.5e9 < capacity.peak_estimate(1_000_000) < 4.5e9  # and 3.5 GB at 1,000,000 rows
    # the loop closure's job: it fits at most fit_rows rows, 130 kB each
    assert capacity.peak_estimate(30_000, fit_rows=20_000) == pytest.approx(0.5e9 + 1.5e3 * 30_000 + 1.3e5 * 20_000)
    assert capacity.peak_estimate(30_000, fit_rows=21_000) > 3.24e9  # the loop measured 3.24 GB fitting 21,000 rows
    assert capacity.peak_estimate(30_000, fit_rows=20_000) > capacity.peak_estimate(30_000)
    assert 3.5e9 < capacity.peak_estimate(1_000_000, fit_rows=20_000) < 5e9  # measured 3.5 GB (accuracy), 3.4 (loop)
    data = read_campaign(make_campaign(tmp_path, tables={SENSOR: sensor_table()}), repo_root=REPO)
    summary = campaigns.summarize(data, memory_limit=2e9)
    assert summary["memory"] == {"largest_sensor_rows": 9, "estimated_peak_gb": pytest.approx(0.5003015)}
    fitted = campaigns.summarize(data, memory_limit=2e9, fit_rows=20_000)["memory"]["estimated_peak_gb"]
    assert fitted == pytest.approx(0.5 + 1.5e-6 * 9 + 1.3e-4 * 9)  # the loop fits all 9 rows
    assert campaigns.summarize(data) == summary  # the limit is not recorded: the same bytes on every machine
    with pytest.raises(
        InputError,
        match=r"demo: 9 rows in its largest sensor: .* would need about 0\.5 GB, more than "
        r"the 0\.1 GB a job may use \(max_job_memory_gb",
    ):
        campaigns.summarize(data, memory_limit=0.1e9)


def test_a_job_asks_for_its_peak_and_its_own_snakemake_and_more_on_a_retry():
    """The memory a workflow job asks a cluster for: the peak estimate plus the job's Snakemake
    (measured on SLURM at about 520 MB beside the script: the 8 jobs SLURM killed at the estimate
    alone), half as much again on each retry."""
    from remaster.campaigns import capacity

    first = capacity.job_request_mb(1_000, fit_rows=20_000)
    # the UR5 campaign's request: the loop fits its 1,000 rows (130 MB), more than its accuracy's 32 MB
    assert first == int((0.5e9 + 1.5e6 + 130e6 + 768e6) / 1e6) + 1 == 1400
    assert capacity.job_request_mb(1_000, attempt=2, fit_rows=20_000) == int(1.5 * (1.3995e9) / 1e6) + 1
    assert capacity.job_request_mb(1_000) == int((0.5e9 + 33.5e6 + 768e6) / 1e6) + 1  # the accuracy's alone
    assert capacity.job_request_mb(100_000) > capacity.peak_estimate(100_000) / 1e6 + 520  # above the measured cost


# --------------------------------------------------------------------------- a full-pose probe


def full_pose(table: pd.DataFrame | None = None, seed: int = 1) -> pd.DataFrame:
    """A valid table with a probe's orientation as rotation vectors (rad), one row not measured."""
    table = sensor_table() if table is None else table
    rng = np.random.default_rng(seed)
    for axis, column in zip(("rx", "ry", "rz"), rng.uniform(-1.5, 1.5, (3, len(table)))):
        table[axis] = column
    table.loc[4, ["rx", "ry", "rz"]] = np.nan
    return table


def full_pose_metadata(**sensor) -> dict:
    meta = metadata()
    meta["sensors"][SENSOR].update({"orientation_noise": 1.7e-4, "probe_rotation": [0.0, 0.0, 0.5], **sensor})
    return meta


def test_a_full_pose_probe_is_read_with_its_noise_and_mounting(tmp_path):
    table = full_pose()
    campaign = read_campaign(make_campaign(tmp_path, full_pose_metadata(), {SENSOR: table}), repo_root=REPO)
    sensor = campaign.sensors[SENSOR]
    assert sensor.has_orientation and sensor.orientation_noise == 1.7e-4
    np.testing.assert_allclose(
        sensor.probe_rotation[:2, :2], [[math.cos(0.5), -math.sin(0.5)], [math.sin(0.5), math.cos(0.5)]]
    )
    rotations = sensor.orientations([3, 4])
    assert np.isnan(rotations[1]).all()
    np.testing.assert_allclose(rotations[0] @ rotations[0].T, np.eye(3), atol=1e-12)


FULL_POSE_TABLE_ERRORS = {
    # case: (mutation, column(s) named, rows named or None, words in the message)
    "rz missing": (lambda t: t.drop(columns="rz"), "rz", None, "missing column"),
    "partial nan": (with_values("ry", [2], np.nan), "rx, ry, rz", [2], "not all"),
    "orientation of an unseen marker": (with_values(["x", "y", "z"], [5], np.nan), "rx, ry, rz", [5], "not seen"),
    "degrees": (with_values("rx", [1, 6], 90.0), "rx, ry, rz", [1, 6], "longer than pi"),
    "float32": (retyped("rx", np.float32), "rx", None, "float64"),
}


@pytest.mark.parametrize("case", FULL_POSE_TABLE_ERRORS)
def test_full_pose_table_errors_name_file_column_and_rows(tmp_path, case):
    mutate, column, rows, words = FULL_POSE_TABLE_ERRORS[case]
    problem = read_error(make_campaign(tmp_path, full_pose_metadata(), {SENSOR: mutate(full_pose())}))
    assert str(problem).startswith(str(tmp_path / "demo" / f"{SENSOR}.parquet"))
    assert problem.key == column and problem.rows == rows and words in str(problem)


@pytest.mark.parametrize(
    "meta, table, key, words",
    [
        (metadata(), full_pose(), "orientation_noise", "need the sensor's orientation_noise"),
        (full_pose_metadata(probe_rotation=None), full_pose(), "probe_rotation", "need the sensor's orientation_noise"),
        (full_pose_metadata(orientation_noise=0.5), full_pose(), "orientation_noise", "not degrees"),
        (full_pose_metadata(probe_rotation=[0.0, 1.0]), full_pose(), "probe_rotation", "rotation vector"),
        (full_pose_metadata(), sensor_table(), None, "no orientation columns"),
    ],
    ids=[
        "columns without noise",
        "columns without mounting",
        "noise in degrees",
        "mounting of two numbers",
        "keys without columns",
    ],
)
def test_full_pose_keys_name_campaign_yaml_and_the_key(tmp_path, meta, table, key, words):
    meta = json.loads(json.dumps(meta, default=str))
    meta["sensors"][SENSOR] = {k: v for k, v in meta["sensors"][SENSOR].items() if v is not None}
    problem = read_error(make_campaign(tmp_path, meta, {SENSOR: table}))
    assert problem.file.endswith("campaign.yaml") and words in str(problem)
    assert problem.key == f"sensors/{SENSOR}" + (f"/{key}" if key else "")


def test_per_point_stds_stand_for_the_stated_noise_beside_an_orientation(tmp_path):
    """With per-point std columns the sensor needs no stated noise: the orientations are weighed
    against the RMS of the stds, the position noise the fit's sigma then stands for."""
    from remaster.inference.readings import orientation_fields

    meta = full_pose_metadata()
    del meta["sensors"][SENSOR]["noise"]
    table = full_pose().assign(std=np.linspace(1e-5, 3e-5, 9))
    sensor = read_campaign(make_campaign(tmp_path, meta, {SENSOR: table}), repo_root=REPO).sensors[SENSOR]
    weight = orientation_fields(sensor, [0, 1])["orientation_weight"]
    assert weight == pytest.approx(math.sqrt(np.mean(np.linspace(1e-5, 3e-5, 9) ** 2)) / 1.7e-4)


def test_the_users_tools_are_read_in_metres_of_the_flange_frame(tmp_path):
    meta = metadata() | {"tools": {"gripper": [0.0, 0.0, 0.15], "probe": [0.1, 0, 0.1]}}
    campaign = read_campaign(make_campaign(tmp_path, meta), repo_root=REPO)
    assert list(campaign.tools) == ["gripper", "probe"]
    np.testing.assert_array_equal(campaign.tools["probe"], [0.1, 0.0, 0.1])
    assert read_campaign(make_campaign(tmp_path, name="plain"), repo_root=REPO).tools == {}


@pytest.mark.parametrize(
    "tools, key, message",
    [
        ({"gripper": [0.0, 0.0, 150.0]}, "tools/gripper", "looks like mm written for m"),
        ({"gripper": [0.0, 0.15]}, "tools/gripper", "3 finite numbers"),
        ({"gripper": [0.0, float("nan"), 0.1]}, "tools/gripper", "3 finite numbers"),
        ([[0.0, 0.0, 0.15]], "tools", "mapping"),
    ],
)
def test_a_tool_in_millimetres_or_not_a_point_is_refused_naming_it(tmp_path, tools, key, message):
    error = read_error(make_campaign(tmp_path, metadata() | {"tools": tools}))
    assert error.key == key and message in str(error) and "campaign.yaml" in str(error)


def test_the_robot_section_for_planning_follows_every_change_of_campaign_yaml(tmp_path):
    """Planning asks for campaign.yaml's robot section many times and reads it once per change: an
    edit is seen at the next call, what it returns cannot be changed by a caller, and a file that is
    missing or does not parse gives {} (reading the campaign says why)."""
    path = tmp_path / "campaign.yaml"
    assert robot_section(tmp_path) == {}
    path.write_text("robot:\n  urdf: a.urdf\n", encoding="utf-8")
    first = robot_section(tmp_path)
    assert dict(first) == {"urdf": "a.urdf"} and robot_section(tmp_path) is first
    with pytest.raises(TypeError):
        first["urdf"] = "b.urdf"
    path.write_text("robot:\n  urdf: another.urdf\n", encoding="utf-8")
    assert dict(robot_section(tmp_path)) == {"urdf": "another.urdf"}
    path.write_text("robot: [unclosed\n", encoding="utf-8")
    assert robot_section(tmp_path) == {}
