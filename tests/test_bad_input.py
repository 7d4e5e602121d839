"""Bad input gets a clear error naming the file, key or column and rows, a non-zero exit and no
partial result (docs/bad-input.md). One test per catalogue entry not already proved elsewhere:
tests/campaigns/test_campaign.py, tests/robot/test_kinematics.py and tests/robot/test_registration.py hold the others."""

from __future__ import annotations

import errno
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from remaster import cli, configuration, files
from remaster import results as results_module
from remaster.campaigns import folders, scenario
from remaster.campaigns.campaign import JOINT_MARGIN, minimum_optimization_points, summarize
from remaster.errors import InputError, KinematicsError, require_columns
from remaster.inference import metrics
from remaster.reporting import figures
from remaster.robot import kinematics, registration

from .campaigns.test_campaign import SENSOR, SMALL_DH, make_campaign, metadata, read_error, sensor_table
from .conftest import REPO, SNAKEMAKE, validated_config

TINY_FIT = {
    "fit": {
        "paper": {"chains": 2, "samples": 300, "burn_in": 200},
        "default": {"chains": 2, "samples": 300, "burn_in": 100},
        "emcee": {"walkers": 32, "steps": 200, "burn_in": 100},
    },
    "accuracy": {"draws": 200, "random_configurations": 100},
    "loop_closure": {"mcmc": {"chains": 2, "samples": 600, "burn_in": 300}},
}


def parquet(folder: Path) -> str:
    return str(folder / f"{SENSOR}.parquet")


# --------------------------------------------------------------------------- campaign.yaml


def test_misspelt_top_level_key_is_named_with_a_guess(tmp_path):
    meta = metadata()
    meta["sensor"] = meta.pop("sensors")
    problem = read_error(make_campaign(tmp_path, meta))
    assert problem.key == "sensors"
    assert str(problem) == (
        f"{tmp_path / 'demo' / 'campaign.yaml'}: sensors: missing required key (misspelt? sensor -> sensors)"
    )


def test_misspelt_sensor_key_is_named_with_a_guess(tmp_path):
    meta = metadata()
    meta["sensors"][SENSOR]["markr"] = meta["sensors"][SENSOR].pop("marker")
    problem = read_error(make_campaign(tmp_path, meta))
    assert problem.key == f"sensors/{SENSOR}/markr"
    assert "unknown key" in str(problem) and "markr -> marker" in str(problem)


def test_campaign_yaml_that_is_not_yaml_names_file_and_line(tmp_path):
    folder = make_campaign(tmp_path)
    (folder / "campaign.yaml").write_text("name: demo\nrobot: {urdf: [x\n")
    problem = read_error(folder)
    assert str(problem).startswith(f"{folder / 'campaign.yaml'}: not valid YAML") and "line" in str(problem)


def test_campaign_yaml_that_is_not_a_mapping(tmp_path):
    folder = make_campaign(tmp_path)
    (folder / "campaign.yaml").write_text("- name: demo\n- date: 2018-06-12\n")
    problem = read_error(folder)
    assert str(problem) == f"{folder / 'campaign.yaml'}: must be a mapping, got list"


def test_missing_campaign_yaml_or_folder(tmp_path):
    folder = make_campaign(tmp_path)
    (folder / "campaign.yaml").unlink()
    assert str(read_error(folder)) == f"{folder / 'campaign.yaml'}: file not found"
    assert "no such directory" in str(read_error(tmp_path / "nowhere"))


# --------------------------------------------------------------------------- <sensor>.parquet


def test_joints_in_degrees_beyond_one_turn_are_refused(tmp_path):
    """A DH robot has no limits: readings beyond +-(2 pi + margin) are degrees whatever the robot."""
    table = sensor_table(3)
    table.loc[[2, 5], "q2"] = [95.0, -30.0]  # degrees
    folder = make_campaign(tmp_path, metadata(robot={"dh": SMALL_DH}), {SENSOR: table})
    problem = read_error(folder)
    assert problem.file == parquet(folder) and problem.key == "q2" and problem.rows == [2, 5]
    assert "looks like degrees stored as radians" in str(problem) and "up to 95" in str(problem)


def test_one_broken_row_of_100k_is_named(tmp_path):
    """At scale the checks still name the row: one NaN joint value in a 100,000-row campaign."""
    table = sensor_table(n_optimization=70_000, n_validation=30_000, seed=4)
    table.loc[73_456, "q3"] = np.nan
    problem = read_error(make_campaign(tmp_path, tables={SENSOR: table}))
    assert problem.key == "q3" and problem.rows == [73_456] and "non-finite joint values (row 73456)" in str(problem)


def test_a_whole_table_in_degrees_is_refused(tmp_path):
    table = sensor_table()
    columns = [f"q{j}" for j in range(1, 8)]
    table[columns] = np.degrees(table[columns])
    problem = read_error(make_campaign(tmp_path, tables={SENSOR: table}))
    assert problem.key == ", ".join(columns) and "degrees" in str(problem)


def test_joints_beyond_the_limits_by_far_are_refused_near_ones_kept(tmp_path, iiwa):
    """The iiwa's joint 2 stops at 120 deg (2.094 rad): 4 (degrees stored as rad) is beyond it by
    far; a reading just past the limit (within the 10 deg margin) is a controller's and is kept."""
    table = sensor_table()
    table.loc[[1, 4], "q2"] = 4.0
    problem = read_error(make_campaign(tmp_path / "far", tables={SENSOR: table}))
    assert problem.key == "q2" and problem.rows == [1, 4]
    assert "outside the robot's limits by more than 10 deg" in str(problem) and "[-2.094, 2.094]" in str(problem)
    table.loc[[1, 4], "q2"] = iiwa.upper[1] + 0.5 * JOINT_MARGIN
    campaign = folders.read_campaign(make_campaign(tmp_path / "near", tables={SENSOR: table}), repo_root=REPO)
    assert campaign.sensors[SENSOR].q()[1, 1] == pytest.approx(iiwa.upper[1] + 0.5 * JOINT_MARGIN)


def test_unreadable_parquet_names_the_file(tmp_path):
    folder = make_campaign(tmp_path)
    Path(parquet(folder)).write_bytes(b"PAR1 this is not a parquet file")
    problem = read_error(folder)
    assert str(problem).startswith(f"{parquet(folder)}: cannot read Parquet")


def test_too_few_optimization_configurations(tmp_path):
    needed = minimum_optimization_points(7)
    assert needed == 5  # 3 x 5 = 15 coordinates > 6 registration + 7 zero-offsets + sigma
    table = sensor_table(n_optimization=4, n_validation=3)
    problem = read_error(make_campaign(tmp_path, tables={SENSOR: table}))
    assert problem.key == "set" and problem.rows == [0, 1, 2, 3]
    assert "has 4 configuration(s) with a measured marker; the fit needs at least 5" in str(problem)


def test_unseen_markers_leaving_too_few_optimization_points(tmp_path):
    table = sensor_table(n_optimization=6)
    table.loc[[0, 3], ["x", "y", "z"]] = np.nan
    problem = read_error(make_campaign(tmp_path, tables={SENSOR: table}))
    assert problem.key == "set" and "has 4 configuration(s)" in str(problem)


def test_collinear_optimization_points_are_refused(tmp_path):
    table = sensor_table()
    rows = table.index[table["set"] == "optimization"]
    table.loc[rows, ["x", "y", "z"]] = np.outer(np.linspace(0.5, 1.5, len(rows)), [1.0, 0.4, 0.2])
    problem = read_error(make_campaign(tmp_path, tables={SENSOR: table}))
    assert problem.file == parquet(tmp_path / "demo") and problem.key == "x, y, z"
    assert problem.rows == list(rows) and "lie on one line" in str(problem)


def test_empty_validation_set_is_read_and_reported_empty(tmp_path):
    """Not an error: the contract allows it. The summary says 0 validation configurations and
    the accuracy metrics of an empty set have count 0 and no number (NaN), never an invented one."""
    table = sensor_table(n_optimization=8, n_validation=0)
    campaign = folders.read_campaign(make_campaign(tmp_path, tables={SENSOR: table}), repo_root=REPO)
    sets = summarize(campaign)["sensors"][SENSOR]["sets"]
    assert sets["validation"] == {"configurations": 0, "poses": 0, "measured": 0}
    assert sets["optimization"]["configurations"] == 8
    sensor = campaign.sensors[SENSOR]
    relative = metrics.relative_errors(
        sensor.positions("validation"),
        sensor.positions("validation"),
        sensor.table.loc[sensor.set_mask("validation"), "pose"].to_numpy(),
    )
    assert relative.shape == (0,)
    summary = metrics.error_summary(relative)
    assert summary["count"] == 0 and math.isnan(summary["mean"])


# --------------------------------------------------------------------------- robot model

CLOSED_LOOP = """<robot name="loop"><link name="base"/><link name="a"/><link name="b"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/></joint>
  <joint name="j3" type="revolute"><parent link="base"/><child link="b"/><axis xyz="0 1 0"/></joint>
  <joint name="flange" type="fixed"><parent link="b"/><child link="tool"/></joint></robot>"""


def small_urdf_campaign(tmp_path, urdf_text):
    folder = make_campaign(
        tmp_path, metadata(robot={"urdf": "robot.urdf", "base": "base", "flange": "tool"}), {SENSOR: sensor_table(3)}
    )
    (folder / "robot.urdf").write_text(urdf_text)
    return folder


def test_non_serial_urdf_in_a_campaign_names_the_urdf(tmp_path):
    folder = small_urdf_campaign(tmp_path, CLOSED_LOOP)
    problem = read_error(folder, KinematicsError)
    assert problem.file == str(folder / "robot.urdf") and "not a serial chain" in str(problem)


def test_unreadable_urdf_numbers_name_file_and_element(tmp_path):
    from .campaigns.test_campaign import SMALL_URDF

    bad_limit = SMALL_URDF.replace(
        '<joint name="j2" type="revolute">', '<joint name="j2" type="revolute"><limit lower="-1.5" upper="one"/>'
    )
    problem = read_error(small_urdf_campaign(tmp_path / "limit", bad_limit), KinematicsError)
    urdf = tmp_path / "limit" / "demo" / "robot.urdf"
    assert str(problem) == f"{urdf}: joint j2/limit/upper: cannot read a number from 'one'"
    bad_origin = SMALL_URDF.replace('<origin xyz="0.4 0 0"/>', '<origin xyz="0.4 0"/>')
    problem = read_error(small_urdf_campaign(tmp_path / "origin", bad_origin), KinematicsError)
    assert problem.file.endswith("robot.urdf") and problem.key == "joint j3/origin/xyz"


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ('<origin xyz="0.4 0 0"/>', '<origin xyz="0.4 nan 0"/>', "joint j3/origin/xyz"),
        ('<origin xyz="0.2 0 0"/>', '<origin xyz="0.2 0 0" rpy="0 inf 0"/>', "joint flange/origin/rpy"),
        (
            '<child link="l3"/>\n    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>',
            '<child link="l3"/>\n    <origin xyz="0.4 0 0"/><axis xyz="0 NaN 1"/>',
            "joint j3/axis",
        ),
    ],
    ids=["origin nan", "rpy inf", "axis nan"],
)
def test_non_finite_urdf_origins_and_axes_name_the_urdf_and_the_joint(tmp_path, old, new, key):
    """A NaN in a joint's origin used to be read and to surface at the fit as 'points_robot:
    non-finite point coordinates', naming neither the URDF nor the joint."""
    from .campaigns.test_campaign import SMALL_URDF

    assert old in SMALL_URDF
    problem = read_error(small_urdf_campaign(tmp_path, SMALL_URDF.replace(old, new)), KinematicsError)
    assert str(problem).startswith(f"{tmp_path / 'demo' / 'robot.urdf'}: {key}: non-finite number(s) in ")
    assert problem.key == key


@pytest.mark.parametrize(
    ("limit", "key", "text"),
    [
        ('<limit lower="-2.0" upper="inf"/>', "joint j2/limit/upper", "'inf'"),
        ('<limit lower="-INF" upper="2.0"/>', "joint j2/limit/lower", "'-INF'"),
        ('<limit lower="-2.0" upper="nan"/>', "joint j2/limit/upper", "'nan'"),
    ],
    ids=["upper inf", "lower -inf", "upper nan"],
)
def test_a_non_finite_urdf_joint_limit_names_the_urdf_the_joint_and_the_key(tmp_path, limit, key, text):
    """An infinite limit used to pass without a word, and with it every reading of that joint
    passed the check of degrees stored as radians against the limits."""
    from .campaigns.test_campaign import SMALL_URDF

    old = '<joint name="j2" type="revolute">'
    assert old in SMALL_URDF
    problem = read_error(small_urdf_campaign(tmp_path, SMALL_URDF.replace(old, old + limit)), KinematicsError)
    assert str(problem) == (
        f"{tmp_path / 'demo' / 'robot.urdf'}: {key}: non-finite number {text}: needs a finite number (rad); "
        'a joint that turns without end is type="continuous", which has no limits'
    )
    assert problem.key == key


def _not_utf8(path: Path) -> None:
    path.write_bytes(b"<?xml version='1.0'?>\n<robot name='\xe9'/>\n")  # Latin-1, not UTF-8


def _a_directory(path: Path) -> None:
    path.unlink(missing_ok=True)
    path.mkdir()


def _a_symlink_loop(path: Path) -> None:
    path.unlink(missing_ok=True)
    path.symlink_to(path.name)


@pytest.mark.parametrize(
    ("spoil", "shown"),
    [
        (_not_utf8, "line 2: not UTF-8 text: byte 0xe9 (invalid continuation byte): save the file as UTF-8"),
        (_a_directory, "is a directory, not a file"),
        (_a_symlink_loop, "cannot read: Too many levels of symbolic links"),
    ],
    ids=["not utf-8", "directory", "symlink loop"],
)
def test_unreadable_files_are_named_not_a_traceback(tmp_path, spoil, shown):
    """A URDF, campaign.yaml, a JSON report or a CSV that is not UTF-8, a directory, or a symlink
    loop used to end in UnicodeDecodeError, IsADirectoryError or OSError naming no input."""
    from .campaigns.test_campaign import SMALL_URDF

    folder = small_urdf_campaign(tmp_path, SMALL_URDF)
    spoil(folder / "robot.urdf")
    problem = read_error(folder)
    assert str(problem) == f"{folder / 'robot.urdf'}: {shown}"
    spoil(folder / "campaign.yaml")
    assert str(read_error(folder)) == f"{folder / 'campaign.yaml'}: {shown}"
    if spoil is _a_directory:  # a folder named like a sensor's table is no table either
        fresh = small_urdf_campaign(tmp_path / "fresh", SMALL_URDF)
        _a_directory(fresh / f"{SENSOR}.parquet")
        assert str(read_error(fresh)) == f"{fresh / SENSOR}.parquet: {shown}"
    for reader in (files.read_json, files.read_yaml, files.read_csv):
        path = tmp_path / f"file.{reader.__name__}"
        path.write_text("{}")
        spoil(path)
        with pytest.raises(InputError) as info:
            reader(path)
        assert str(info.value).startswith(f"{path}: ")
        if reader is not files.read_csv:  # pandas says itself what it cannot decode
            assert str(info.value) == f"{path}: {shown}"


def test_urdf_limits_upside_down(tmp_path):
    from .campaigns.test_campaign import SMALL_URDF

    swapped = SMALL_URDF.replace(
        '<joint name="j1" type="revolute">', '<joint name="j1" type="revolute"><limit lower="1.0" upper="-1.0"/>'
    )
    with pytest.raises(KinematicsError, match=r"robot.urdf: joint j1/limit: lower limit 1 is above upper limit -1"):
        kinematics.chain_from_urdf(swapped, "base", "tool", source="robot.urdf")


@pytest.mark.parametrize(
    ("key", "value", "shown"),
    [
        ("marker", [-100.0, 0.0, 20.0], "100 m is not below 1 m"),  # mm: a certificate with a 98 m error
        ("noise", 10.0, "10 m is not below 0.01 m"),
        ("noise", 0.01, "0.01 m is not below 0.01 m"),  # 10 um written as mm
        ("mpe", 0.025, "0.025 m is not below 0.01 m"),
    ],
    ids=["marker in mm", "noise 10", "noise 0.01", "mpe in mm"],
)
def test_sensor_lengths_in_millimetres_are_refused(tmp_path, key, value, shown):
    meta = metadata()
    meta["sensors"][SENSOR][key] = value
    problem = read_error(make_campaign(tmp_path, meta))
    assert str(problem).startswith(f"{tmp_path / 'demo' / 'campaign.yaml'}: sensors/{SENSOR}/{key}: {shown}")
    assert "looks like mm written for m" in str(problem)


def test_plausible_sensor_lengths_are_kept(tmp_path):
    meta = metadata()
    meta["sensors"][SENSOR].update(marker=[0.5, -0.3, 0.2], noise=5e-3, mpe=9e-3)
    sensor = folders.read_campaign(make_campaign(tmp_path, meta), repo_root=REPO).sensors[SENSOR]
    assert (sensor.noise, sensor.mpe) == (5e-3, 9e-3)


@pytest.mark.parametrize(
    ("value", "shown"),
    [
        ("[0, 0, 90]", "looks like degrees: 90 deg = 1.571 rad (write radians)"),  # was taken modulo 2 pi
        ("[1.0e+300, 0, 0]", "not a rotation vector in rad, nor in degrees (1e+300 deg is beyond a turn)"),
        ("[0, 0, .inf]", "must be 3 finite numbers: a rotation vector (rad), got [0, 0, inf]"),
        ("[0, .nan, 0]", "must be 3 finite numbers: a rotation vector (rad), got [0, nan, 0]"),
    ],
    ids=["degrees", "huge", "inf", "nan"],
)
def test_a_probe_rotation_beyond_pi_or_not_finite_is_refused(tmp_path, value, shown):
    from .campaigns.test_campaign import full_pose, full_pose_metadata

    folder = make_campaign(tmp_path, full_pose_metadata(probe_rotation=[0.0, 0.0, 0.25]), {SENSOR: full_pose()})
    text = (folder / "campaign.yaml").read_text()
    (folder / "campaign.yaml").write_text(text.replace("probe_rotation: [0.0, 0.0, 0.25]", f"probe_rotation: {value}"))
    problem = read_error(folder)
    assert str(problem).startswith(f"{folder / 'campaign.yaml'}: sensors/{SENSOR}/probe_rotation: ")
    assert problem.key == f"sensors/{SENSOR}/probe_rotation" and shown in str(problem)


def test_a_probe_rotation_of_half_a_turn_is_kept(tmp_path):
    """pi written 3.1416 (7e-6 rad beyond it) is half a turn, not degrees: read as such."""
    from .campaigns.test_campaign import full_pose, full_pose_metadata

    meta = full_pose_metadata(probe_rotation=[0.0, 0.0, 3.1416])
    sensor = folders.read_campaign(make_campaign(tmp_path, meta, {SENSOR: full_pose()}), repo_root=REPO).sensors[SENSOR]
    np.testing.assert_allclose(sensor.probe_rotation, np.diag([-1.0, -1.0, 1.0]), atol=1e-5)


def test_a_dh_flange_that_mirrors_is_refused(tmp_path):
    """An orthonormal flange rotation of determinant -1 (an axis flipped) is a reflection, no rigid
    motion: it used to pass the check of orthonormality alone."""
    mirrored = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.1], [0.0, 0.0, 0.0, 1.0]]
    meta = metadata(robot={"dh": {**SMALL_DH, "flange": mirrored}})
    problem = read_error(make_campaign(tmp_path, meta, {SENSOR: sensor_table(3)}), KinematicsError)
    assert str(problem).startswith(f"{tmp_path / 'demo' / 'campaign.yaml'}: robot/dh/flange: ")
    assert "determinant is -1 (a reflection, not a rotation" in str(problem)
    turned = [[0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.1], [0.0, 0.0, 0.0, 1.0]]
    assert kinematics.chain_from_dh(SMALL_DH["rows"], flange=turned).n_joints == 3  # a rotation is kept


def test_robot_lengths_in_millimetres_are_refused(tmp_path):
    from .campaigns.test_campaign import SMALL_URDF

    in_mm = {**SMALL_DH, "rows": [SMALL_DH["rows"][0], [400.0, 0.0, 0.0, 0.0], SMALL_DH["rows"][2]]}
    problem = read_error(
        make_campaign(tmp_path / "dh", metadata(robot={"dh": in_mm}), {SENSOR: sensor_table(3)}), KinematicsError
    )
    assert str(problem).startswith(
        f"{tmp_path / 'dh' / 'demo' / 'campaign.yaml'}: robot/dh/rows: 400 m is not below 5 m"
    )
    assert "looks like mm" in str(problem) and problem.rows == [1]
    flange = [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 150.0], [0, 0, 0, 1.0]]
    problem = read_error(
        make_campaign(
            tmp_path / "flange", metadata(robot={"dh": {**SMALL_DH, "flange": flange}}), {SENSOR: sensor_table(3)}
        ),
        KinematicsError,
    )
    assert "robot/dh/flange: 150 m is not below 5 m" in str(problem) and "looks like mm" in str(problem)
    problem = read_error(
        small_urdf_campaign(
            tmp_path / "urdf", SMALL_URDF.replace('<origin xyz="0.4 0 0"/>', '<origin xyz="400 0 0"/>')
        ),
        KinematicsError,
    )
    urdf = tmp_path / "urdf" / "demo" / "robot.urdf"
    assert str(problem).startswith(f"{urdf}: joint j3/origin/xyz: 400 m is not below 5 m")
    assert "looks like mm" in str(problem)


def test_a_dh_table_without_length_is_refused_and_a_fit_with_no_free_zero_offset_is_drawn_as_a_note(tmp_path):
    """A DH table whose every a and d is 0 (joint axes through one point: the arm's reach is 0) used
    to be read; its fit held every zero-offset and the figures died dividing by their count (0)."""
    rows = [[0.0, math.pi / 2, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, -math.pi / 2, 0.0, 0.1]]
    problem = read_error(
        make_campaign(tmp_path, metadata(robot={"dh": {**SMALL_DH, "rows": rows}}), {SENSOR: sensor_table(3)}),
        KinematicsError,
    )
    assert str(problem).startswith(
        f"{tmp_path / 'demo' / 'campaign.yaml'}: robot/dh/rows: every link length (a and d of every row) is 0"
    )
    assert problem.key == "robot/dh/rows"
    # one length is enough to be read
    rows[1][0] = 0.4
    folders.read_campaign(
        make_campaign(tmp_path / "long", metadata(robot={"dh": {**SMALL_DH, "rows": rows}}), {SENSOR: sensor_table(3)}),
        repo_root=REPO,
    )
    # whatever else leaves the fit no free zero-offset (a one-joint robot), its figures say so
    held = pd.DataFrame({"step": [0, 1], "chain": [0, 0], "registration.x": [0.0, 0.1]})
    for figure in (figures.zero_offset_trace(held, 1, "t"), figures.zero_offset_histograms(held, "t")):
        assert figures.NO_FREE_ZERO_OFFSET in [text.get_text() for ax in figure.axes for text in ax.texts]


# --------------------------------------------------------------------------- registration


def test_three_point_registration_refuses_more_than_three_points(rng):
    points = rng.uniform(-1, 1, (4, 3))
    with pytest.raises(InputError, match="points_robot: the three-point registration takes exactly 3 points, got 4"):
        registration.three_point(points, points)


def test_kabsch_refuses_weights_that_would_give_a_quiet_nan(rng):
    points = rng.uniform(-1, 1, (5, 3))
    with pytest.raises(InputError, match=r"weights: weights must be finite and not negative \(rows 1, 3\)"):
        registration.kabsch(points, points, weights=[1.0, -1.0, 1.0, np.nan, 1.0])
    with pytest.raises(InputError, match="every weight is zero"):
        registration.kabsch(points, points, weights=np.zeros(5))
    with pytest.raises(InputError, match="expected 5 weights"):
        registration.kabsch(points, points, weights=np.ones(4))


# --------------------------------------------------------------------------- config.yaml (workflow)


def dry_run(tmp_path, settings: dict) -> subprocess.CompletedProcess:
    config = files.write_yaml(tmp_path / "bad-config.yaml", settings)
    return subprocess.run(
        SNAKEMAKE + ["-n", "--configfile", str(config)], cwd=REPO, capture_output=True, text=True, timeout=300
    )


def real_run(tmp_path, raw) -> tuple[subprocess.CompletedProcess, Path]:
    """`snakemake -j1` on the campaigns in `raw` with the tiny fit settings: (its result, the results folder)."""
    results = tmp_path / "results"
    config = files.write_yaml(tmp_path / "config.yaml", {"raw_dir": str(raw), "results_dir": str(results), **TINY_FIT})
    result = subprocess.run(
        SNAKEMAKE + ["-j1", "--configfile", str(config)], cwd=REPO, capture_output=True, text=True, timeout=1800
    )
    return result, results


def assert_refused(result: subprocess.CompletedProcess, *fragments: str) -> None:
    output = result.stdout + result.stderr
    assert result.returncode != 0, output[-2000:]
    for fragment in fragments:
        assert fragment in output, output[-2000:]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, iiwa):
    """A small simulated campaign folder `tiny` under raw/ (outside the repository)."""
    root = tmp_path_factory.mktemp("bad_input_workflow")
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-twin.yaml")
    spec["name"] = "tiny"
    spec["plan"]["sets"] = {
        "optimization": {"poses": 4, "configurations": 12},
        "validation": {"poses": 2, "configurations": 6},
    }
    out = scenario.simulate(spec, iiwa)
    folders.write_campaign(root / "raw" / "tiny", out.metadata, out.tables)
    return root


# The workflow validates its configuration against the schema, then refuses with
# `configuration.workflow_run` what the schema cannot check: the tests below call both in-process
# (`validated_config`: the schema's defaults filled in as Snakemake fills them).
# test_config_raw_dir_that_does_not_exist shows such a refusal reaching the user through Snakemake,
# tests/workflow/test_workflow.py::test_bad_config_is_refused_by_the_schema a schema's refusal.
CONFIG = "bad-config.yaml"  # the config file(s) a refusal names


def config_refusal(settings: dict) -> InputError:
    """What the workflow refuses `settings` with, after the schema (`configuration.workflow_run`)."""
    with pytest.raises(InputError) as refused:
        configuration.workflow_run(validated_config(settings), CONFIG)
    return refused.value


def test_config_misspelt_key():
    with pytest.raises(InputError, match=re.escape("Additional properties are not allowed ('raw_dri' was unexpected)")):
        validated_config({"raw_dri": "data/raw"})


def test_config_key_given_twice(tmp_path):
    """remaster's loader refuses the file, which Snakemake would read keeping the last value; the
    workflow reads its YAML config files again with it before anything else (common.smk), as
    tests/campaigns/test_safe_loading.py::test_config_with_a_python_tag_is_refused_by_the_workflow
    shows through Snakemake."""
    config = tmp_path / "twice.yaml"
    config.write_text("seed: 1\nseed: 2\n")
    with pytest.raises(InputError) as refused:
        files.read_yaml(config)
    assert str(refused.value).startswith(f"{config}: seed: line 2: duplicate key (first on line 1)")


@pytest.mark.workflow
def test_config_raw_dir_that_does_not_exist(tmp_path):
    """Through Snakemake, a dry run: the refusal names the config file in force and the key, before any job."""
    message = f"raw_dir: '{tmp_path / 'nowhere'}' is not a directory (it should hold one folder per campaign)"
    assert str(config_refusal({"raw_dir": str(tmp_path / "nowhere")})) == f"{CONFIG}: {message}"
    result = dry_run(tmp_path, {"raw_dir": str(tmp_path / "nowhere")})
    assert_refused(result, f"{tmp_path / 'bad-config.yaml'} + config.yaml: {message}")
    assert not (tmp_path / "results").exists()


def test_config_relative_path_leading_outside_the_repository():
    assert str(config_refusal({"results_dir": "../results"})) == (
        f"{CONFIG}: results_dir: '../results' leads outside the repository; relative paths are taken from the "
        "repository root: give an absolute path for a folder elsewhere"
    )


def test_config_results_inside_raw_data(tmp_path):
    raw = tmp_path / "raw"
    raw.mkdir()
    assert str(config_refusal({"raw_dir": str(raw), "results_dir": str(raw / "results")})) == (
        f"{CONFIG}: results_dir: '{raw / 'results'}' overlaps raw_dir '{raw}': generated files and campaign data "
        "must live in separate folders"
    )
    assert not (raw / "results").exists()
    refused = config_refusal({"raw_dir": str(raw), "results_dir": str(tmp_path)})  # containing it
    assert refused.key == "results_dir" and "overlaps raw_dir" in str(refused)


def test_config_results_dir_that_is_a_file(tmp_path):
    (tmp_path / "raw").mkdir()
    (tmp_path / "results.txt").write_text("not a folder")
    refused = config_refusal({"raw_dir": str(tmp_path / "raw"), "results_dir": str(tmp_path / "results.txt")})
    assert str(refused) == f"{CONFIG}: results_dir: '{tmp_path / 'results.txt'}' exists and is not a directory"


def test_config_burn_in_not_shorter_than_the_run():
    assert str(config_refusal({"fit": {"emcee": {"steps": 500, "burn_in": 500}}})) == (
        f"{CONFIG}: fit/emcee/burn_in: 500 is not below fit/emcee/steps = 500: no sample would be kept"
    )
    assert str(config_refusal({"loop_closure": {"mcmc": {"samples": 1000, "burn_in": 1000}}})) == (
        f"{CONFIG}: loop_closure/mcmc/burn_in: 1000 is not below loop_closure/mcmc/samples = 1000: "
        "no sample would be kept"
    )


def test_config_campaign_that_is_not_there(monkeypatch):
    monkeypatch.chdir(REPO)  # the workflow's working folder: raw_dir's default data/raw is taken from it
    assert str(config_refusal({"campaigns": ["kuka-twin", "kuka-twim"]})) == (
        f"{CONFIG}: campaigns: no data/raw/<name>/campaign.yaml for kuka-twim"
    )


def test_config_failed_campaigns_are_not_also_run(monkeypatch):
    """failed_campaigns is what the workflow sets when it runs again on the campaigns that did not
    fail (entry 115): a campaign both failed and run is refused."""
    monkeypatch.chdir(REPO)
    refused = config_refusal({"campaigns": ["kuka-twin"], "failed_campaigns": {"kuka-twin": "InputError: x"}})
    assert str(refused).startswith(f"{CONFIG}: failed_campaigns: kuka-twin also in the run's campaigns")


def test_config_raw_dir_without_any_campaign(tmp_path):
    (tmp_path / "empty").mkdir()
    assert str(config_refusal({"raw_dir": str(tmp_path / "empty")})) == (
        f"{CONFIG}: raw_dir: '{tmp_path / 'empty'}' holds no campaign folder (<name>/campaign.yaml): nothing to process"
    )


def test_config_campaigns_anywhere_by_absolute_path_are_accepted(tmp_path):
    """The decision's other half: raw_dir and results_dir outside the repository, given as absolute
    paths. A dry run of such a configuration plans the campaigns' jobs and writes nothing:
    test_one_unreadable_campaign_does_not_stop_the_others_from_being_planned."""
    for name in ("cell3", "cell1"):
        (tmp_path / "raw" / name).mkdir(parents=True)
        (tmp_path / "raw" / name / "campaign.yaml").write_text(f"name: {name}\n")
    settings = {"raw_dir": str(tmp_path / "raw"), "results_dir": str(tmp_path / "results"), **TINY_FIT}
    run = configuration.workflow_run(validated_config(settings), CONFIG)
    assert run == (str(tmp_path / "raw"), str(tmp_path / "results"), ["cell1", "cell3"])
    assert not (tmp_path / "results").exists()


@pytest.mark.workflow
def test_bad_campaign_fails_the_real_run_and_leaves_no_output(tmp_path, tiny):
    """A campaign whose joints were stored in degrees: `snakemake -j1` exits non-zero, the log of
    the failing job says why, and the failing job leaves no output file."""
    raw = tmp_path / "raw"
    shutil.copytree(tiny / "raw", raw)
    table = pd.read_parquet(raw / "tiny" / "motion_capture.parquet")
    joints = [f"q{j}" for j in range(1, 8)]
    table[joints] = np.degrees(table[joints])
    files.write_parquet(raw / "tiny" / "motion_capture.parquet", table)
    result, results = real_run(tmp_path, raw)
    output = result.stdout + result.stderr
    assert result.returncode != 0, output[-2000:]
    failed = re.findall(r"Error in rule (\w+):", output)
    assert failed and set(failed) <= {"campaign_summary", "registration"}, output[-2000:]
    outputs = {
        "campaign_summary": [results / "tiny" / "campaign" / "summary.json"],
        "registration": [
            results / "tiny" / sensor / "registration.json" for sensor in ("laser_tracker", "motion_capture")
        ],
    }
    for rule in failed:
        assert not any(path.exists() for path in outputs[rule])
    assert [p for p in results.rglob("*") if p.is_file() and "logs" not in p.relative_to(results).parts] == []
    logs = "".join(p.read_text() for p in (results / "logs").rglob("*.log"))
    # q3 is held at 0 by the planner, so 0 deg = 0 rad is not named
    assert "motion_capture.parquet: q1, q2, q4, q5, q6, q7: joint values beyond one turn" in logs
    assert "looks like degrees stored as radians" in logs


def test_the_one_column_check_names_the_file_the_missing_columns_and_what_it_has():
    table = pd.DataFrame(columns=["set", "q1", "q3"])
    require_columns(table, ["set", "q1"], file="plan.csv")  # all there: no error
    with pytest.raises(InputError) as raised:
        require_columns(
            table, ["q1", "q2", "q4"], file="plan.csv", kind="joint", note="the robot has 4 joints", listed=True
        )
    assert str(raised.value) == "plan.csv: q2, q4: missing joint column(s) (the robot has 4 joints; got: set, q1, q3)"
    assert raised.value.file == "plan.csv" and raised.value.key == "q2, q4"
    with pytest.raises(InputError, match=r"^s.parquet: sigma: missing column\(s\) of the posterior samples$"):
        require_columns(table, ["sigma"], file="s.parquet", of="the posterior samples")


DAMAGES = ("empty-parquet", "latin-1-yaml", "yaml-list", "dangling-symlink", "symlink-loop")


@pytest.mark.workflow
def test_one_unreadable_campaign_does_not_stop_the_others_from_being_planned(tmp_path, tiny):
    """Graph building reads no campaign's data: damaged campaigns beside a good one still give a
    plan with every campaign's jobs (a damaged campaign's own first job reports the file with the
    reader's message; `--keep-going` runs the others to the end). One dry run of the five damages,
    each a campaign named after it: a 0-byte Parquet file, a campaign.yaml in Latin-1, one holding
    a list, a Parquet file that is a symbolic link to no file, one that is a loop of links. Such a
    link is not declared as an input, which would stop graph building (MissingInputException): the
    campaign's first job names it, and the good campaign's runs."""
    raw = tmp_path / "raw"
    shutil.copytree(tiny / "raw" / "tiny", raw / "tiny")
    for damage in DAMAGES:
        shutil.copytree(tiny / "raw" / "tiny", raw / damage)
    (raw / "empty-parquet" / "motion_capture.parquet").write_bytes(b"")
    text = (raw / "latin-1-yaml" / "campaign.yaml").read_text(encoding="utf-8")
    (raw / "latin-1-yaml" / "campaign.yaml").write_bytes((text + "# café\n").encode("latin-1"))
    (raw / "yaml-list" / "campaign.yaml").write_text("- 1\n- 2\n", encoding="utf-8")
    links = {"dangling-symlink": tmp_path / "moved" / "motion_capture.parquet"}
    links["symlink-loop"] = raw / "symlink-loop" / "loop.lnk"
    for damage, target in links.items():  # the campaign otherwise sound (named as its folder), but for its link
        metadata = files.read_yaml(raw / damage / "campaign.yaml")
        files.write_yaml(raw / damage / "campaign.yaml", {**metadata, "name": damage})
        (raw / damage / "motion_capture.parquet").unlink()
        (raw / damage / "motion_capture.parquet").symlink_to(target)
    (raw / "symlink-loop" / "loop.lnk").symlink_to(raw / "symlink-loop" / "motion_capture.parquet")
    result = dry_run(tmp_path, {"raw_dir": str(raw), "results_dir": str(tmp_path / "results"), **TINY_FIT})
    assert result.returncode == 0, (result.stdout + result.stderr)[-2000:]
    planned = result.stdout
    for campaign in ("tiny", *DAMAGES):
        assert f"campaign={campaign}" in planned, campaign
    # raw_dir and results_dir outside the repository, by absolute paths: planned, and nothing written
    assert "campaign_summary" in planned and not (tmp_path / "results").exists()
    # the first job of each campaign with a link, and of the good one, for real: each names its link,
    # the good one's runs
    results = tmp_path / "results"
    result = subprocess.run(
        SNAKEMAKE
        + [str(results / c / "campaign" / "summary.json") for c in (*links, "tiny")]
        + ["-j1", "--configfile", str(tmp_path / "bad-config.yaml")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode != 0 and "Error in rule campaign_summary" in result.stdout + result.stderr
    assert (results / "tiny" / "campaign" / "summary.json").is_file()
    reasons = {
        "dangling-symlink": f"a symbolic link to '{links['dangling-symlink']}', which does not exist",
        "symlink-loop": f"a symbolic link (to '{links['symlink-loop']}') that loops back on itself",
    }
    for damage, reason in reasons.items():
        assert not (results / damage / "campaign" / "summary.json").exists()
        link = raw / damage / "motion_capture.parquet"
        assert f"{link}: {reason}" in (results / "logs" / damage / "campaign_summary.log").read_text(), damage


@pytest.mark.workflow
@pytest.mark.slow
def test_one_bad_campaign_fails_its_own_jobs_and_the_others_complete(tmp_path, tiny):
    """A real run of two campaigns, one with a 0-byte Parquet file: `snakemake -j1` (the default
    profile keeps going) exits non-zero, the damaged campaign's job log names its file, and the good
    campaign gets its certificate; what an earlier run left of the damaged one (its certificate, the
    run's report) is removed. The report and the comparison across campaigns are written for the
    good campaign alone (the workflow runs again on it), the damaged one a red row of the report
    naming its job's log and the reader's message; the audit covers the good one only. The good
    one's validation set repeats two optimization rows bit for bit: its certificate says so, naming
    the rows."""
    raw = tmp_path / "raw"
    shutil.copytree(tiny / "raw" / "tiny", raw / "tiny")
    table = pd.read_parquet(raw / "tiny" / "laser_tracker.parquet")
    columns = [c for c in table.columns if c[0] == "q" and c[1:].isdigit()] + ["x", "y", "z"]
    validation = np.flatnonzero(table["set"] == "validation")[:2]
    table.loc[validation, columns] = table.loc[np.flatnonzero(table["set"] == "optimization")[:2], columns].to_numpy()
    table.to_parquet(raw / "tiny" / "laser_tracker.parquet", index=False)
    shutil.copytree(tiny / "raw" / "tiny", raw / "broken")
    metadata = files.read_yaml(raw / "broken" / "campaign.yaml")
    files.write_yaml(raw / "broken" / "campaign.yaml", {**metadata, "name": "broken"})
    (raw / "broken" / "motion_capture.parquet").write_bytes(b"")
    # the good campaign with its laser tracker alone: a second sensor would add jobs, not checks
    (raw / "tiny" / "motion_capture.parquet").unlink()
    files.write_yaml(
        raw / "tiny" / "campaign.yaml",
        {**metadata, "sensors": {"laser_tracker": metadata["sensors"]["laser_tracker"]}},
    )
    earlier = tmp_path / "results"  # what an earlier run left: the broken campaign's certificate, the report
    (earlier / "broken").mkdir(parents=True)
    (earlier / "broken" / "certificate.md").write_text("an earlier run's verdict")
    (earlier / "report.html").write_text("an earlier run's report")
    for made in (earlier / "broken" / "certificate.md", earlier / "report.html"):
        os.utime(made, (946684800, 946684800))  # made before the campaigns changed (2000-01-01)
    result, results = real_run(tmp_path, raw)
    output = result.stdout + result.stderr
    assert result.returncode != 0, output[-2000:]
    assert (results / "tiny" / "certificate.md").is_file(), output[-3000:]
    certificate = (results / "tiny" / "certificate.md").read_text()
    assert "2 of its rows repeat optimization rows bit for bit" in certificate
    assert f"rows {validation[0]}, {validation[1]}, 0-based" in certificate
    assert not (results / "broken" / "certificate.md").exists()  # the earlier one removed: its results failed
    assert not (results / "broken" / "certificate.json").exists()
    assert f"removed {results / 'report.html'}: a result it was made from failed in this run" in output
    logs = "".join(p.read_text() for p in (results / "logs" / "broken").rglob("*.log"))
    assert "motion_capture.parquet" in logs
    # the report of the good campaign, written by the run again on it: the broken one a red row
    assert "broken failed: writing the report and the comparison across campaigns of tiny" in output
    page = (results / "report.html").read_text()
    rows = re.findall(r"<tr class='failed'><td>(.*?)</td><td>(.*?)</td></tr>", page, flags=re.S)
    assert [name for name, _ in rows] == ["broken"], page[:3000]
    message = rows[0][1]
    assert message.startswith("logs/broken/campaign_summary.log: InputError: ")
    assert f"{raw / 'broken' / 'motion_capture.parquet'}: cannot read Parquet" in message
    assert "This run failed for 1 of its 2 campaigns (broken)" in page
    assert "<h2 id='tiny'>tiny</h2>" in page and "<h2 id='broken'>" not in page
    assert "2 of its rows repeat optimization rows bit for bit" in page  # tiny's certificate, in the report
    comparison = results / "comparison"
    assert (comparison / "zero_offsets_over_time.csv").is_file() and (comparison / "transfer.csv").is_file()
    assert set(pd.read_csv(comparison / "transfer.csv")["calibrated_on"]) == {"tiny"}
    audit_record = files.read_json(results / "audit.json")
    assert set(audit_record["campaigns"]) == {"tiny"}
    assert set(audit_record["config"]["failed_campaigns"]) == {"broken"}


def test_a_failed_campaign_is_named_with_the_exception_its_job_log_ends_with(tmp_path):
    """After a failed run: the campaigns whose results are not all there, each with the exception
    its failed job's log ends with (the type without its module); a log of an earlier run, or of
    a job that did not fail, says nothing; a campaign without such a log did not run to its end."""
    import time

    done = tmp_path / "good" / "certificate.json"
    done.parent.mkdir()
    done.write_text("{}")
    earlier = tmp_path / "logs" / "bad" / "tables.log"
    with pytest.raises(InputError), files.log_to(earlier):
        raise InputError("an earlier run's failure", file="old.parquet")
    os.utime(earlier, (946684800, 946684800))
    since = time.time() - 1
    with files.log_to(tmp_path / "logs" / "bad" / "campaign_summary.log") as log:
        log.info("reading the campaign")
    with (
        pytest.raises(np.linalg.LinAlgError),
        files.log_to(tmp_path / "logs" / "bad" / "laser_tracker" / "prepare.log"),
    ):
        try:
            raise KeyError("cause")
        except KeyError:
            raise np.linalg.LinAlgError("Matrix is not positive definite\nat the Laplace mode") from None
    assert results_module.job_failure(tmp_path / "logs" / "bad" / "laser_tracker" / "prepare.log") == (
        "LinAlgError: Matrix is not positive definite\nat the Laplace mode"
    )
    assert results_module.job_failure(tmp_path / "logs" / "bad" / "campaign_summary.log") is None
    assert results_module.job_failure(earlier) == "InputError: old.parquet: an earlier run's failure"
    failed = results_module.failed_campaigns(
        tmp_path,
        {"good": [done], "bad": [tmp_path / "bad" / "certificate.json"], "later": [tmp_path / "later" / "x"]},
        since,
    )
    assert failed == {
        "bad": "logs/bad/laser_tracker/prepare.log: LinAlgError: Matrix is not positive definite\nat the Laplace mode",
        "later": results_module.NOT_RUN,
    }


@pytest.fixture
def read_only(monkeypatch):
    """make(folder): the folder, made read-only. Root ignores permission bits: when the tests run
    as root, the refusals the kernel gives any other user (EACCES on creating a file or a folder in
    it) are given here instead."""
    made = []

    def make(folder: Path) -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        folder.chmod(0o555)
        made.append(folder)
        if os.geteuid() != 0:
            return folder
        inside = [folder.resolve()]

        def within(path) -> bool:
            path = Path(path).resolve()
            return path in inside or any(f in path.parents for f in inside)

        def denied(path) -> PermissionError:
            return PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))

        real_open, real_mkdir = os.open, Path.mkdir

        def refusing_open(path, flags, *args, **kwargs):
            if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT) and within(path):
                raise denied(path)
            return real_open(path, flags, *args, **kwargs)

        def refusing_mkdir(self, *args, **kwargs):
            if within(self) and not self.exists():
                raise denied(self)
            return real_mkdir(self, *args, **kwargs)

        monkeypatch.setattr(os, "open", refusing_open)
        monkeypatch.setattr(Path, "mkdir", refusing_mkdir)
        return folder

    yield make
    for folder in made:
        folder.chmod(0o755)


def test_a_read_only_results_folder_is_named_not_a_traceback(tmp_path, read_only, capsys):
    """A results folder this user cannot write in used to end a run in a raw PermissionError
    traceback (taking the lock, or a job's log): the folder or file is named, before any job, and
    nothing is written. `remaster import` into a read-only --raw-dir: exit 2, the folder named."""
    from .campaigns.test_importer import write_import

    config = write_import(tmp_path)  # before the folder is made read-only
    shelf = read_only(tmp_path / "shelf")
    for results in (shelf, shelf / "results"):  # the folder itself, or a folder to create in it
        with pytest.raises(InputError) as info:
            results_module.take_lock(results)
        assert str(info.value) == (
            f"{results}: cannot write in the results folder: Permission denied: give a results_dir this user "
            "can write (results_dir in config.yaml, or --config results_dir=...)"
        )
    log = shelf / "logs" / "fit.log"
    with pytest.raises(InputError, match=re.escape(f"{log}: cannot write the log: Permission denied")):
        with files.log_to(log):
            pass
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(shelf)]) == 2
    assert capsys.readouterr().err == (
        f"remaster import: error: {shelf / 'cell3'}: cannot write the campaign folder: Permission denied\n"
    )
    assert list(shelf.iterdir()) == []


@pytest.mark.workflow
def test_a_results_folder_another_run_is_writing_is_refused(tmp_path, tiny):
    """Two checkouts given one results_dir: the second run stops before any job, naming the lock and
    its holder, and writes nothing; once the holder is gone its lock is taken over."""
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    try:
        results_module.take_lock(tmp_path / "results", pid=holder.pid)
        result, results = real_run(tmp_path, tiny / "raw")
        assert_refused(
            result, results_module.LOCK_FILE, "another run is writing this results folder", f"process {holder.pid}"
        )
        assert sorted(p.name for p in results.iterdir()) == [results_module.LOCK_FILE]
    finally:
        holder.kill()
        holder.wait()
