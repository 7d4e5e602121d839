"""`remaster import`: hand-written controller and sensor CSV exports become a campaign folder in SI
units; unmatched rows are listed, never dropped; bad cells name the file, the line and the column."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pandas as pd
import pytest

from remaster import cli, files
from remaster.campaigns import folders, importer
from remaster.errors import InputError, quoted

from ..conftest import IIWA_URDF

# A 3-joint arm as standard DH rows: no URDF file needed.
ROBOT = {
    "dh": {"convention": "standard", "rows": [[0.0, math.pi / 2, 0.3, 0.0], [0.4, 0.0, 0.0, 0.0], [0.2, 0.0, 0.0, 0.0]]}
}

CONTROLLER = """\
point,A1,A2,A3,phase,stamp
P1,10,20,30,optimization,2024-05-02T10:00:00
P2,-15.5,45,0,optimization,2024-05-02T10:00:10
P3,90,0,-45,optimization,2024-05-02T10:00:20
P4,0,0,0,validation,2024-05-02T10:00:30
P5,30,60,-90,optimization,2024-05-02T10:00:40
P6,-60,30,45,optimization,2024-05-02T10:00:50
"""

TRACKER = """\
id,X,Y,Z
P3,1000,-250.5,300
P1,1500,0,20

P2,,,
P4,1200.25,10,5
P6,900,400,-100
P5,1100,-300,150
"""
SEEN = [
    [1.5, 0.0, 0.02],
    [np.nan] * 3,
    [1.0, -0.2505, 0.3],
    [1.20025, 0.01, 0.005],
    [1.1, -0.3, 0.15],
    [0.9, 0.4, -0.1],
]
DEGREES = [[10, 20, 30], [-15.5, 45, 0], [90, 0, -45], [0, 0, 0], [30, 60, -90], [-60, 30, 45]]


def write_import(tmp_path, controller=CONTROLLER, tracker=TRACKER, sensor=None, controller_section=None):
    (tmp_path / "controller.csv").write_text(controller, encoding="utf-8")
    (tmp_path / "tracker.csv").write_text(tracker, encoding="utf-8")
    config = {
        "name": "cell3",
        "date": "2024-05-02",
        "description": "hand-written exports",
        "robot": ROBOT,
        "controller": {
            "file": "controller.csv",
            "joints": ["A1", "A2", "A3"],
            "unit": "deg",
            "set": "phase",
            "key": "point",
            "time": "stamp",
            **(controller_section or {}),
        },
        "sensors": {
            "laser_tracker": {
                "kind": "laser_tracker",
                "marker": [-0.1, 0.0, 0.02],
                "noise": 1e-5,
                "file": "tracker.csv",
                "xyz": ["X", "Y", "Z"],
                "unit": "mm",
                "match": "key",
                "key": "id",
                **(sensor or {}),
            }
        },
    }
    files.write_yaml(tmp_path / "import.yaml", config)
    return tmp_path / "import.yaml"


def test_import_by_key_gives_si_values(tmp_path):
    config = write_import(tmp_path)
    folder, report = folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    assert folder == tmp_path / "raw" / "cell3"
    campaign = folders.read_campaign(folder, repo_root=tmp_path)
    table = campaign.sensors["laser_tracker"].table
    assert campaign.n_joints == 3 and campaign.date.isoformat() == "2024-05-02"
    assert table["set"].tolist() == ["optimization"] * 3 + ["validation"] + ["optimization"] * 2
    assert table["pose"].tolist() == [0, 1, 2, 0, 3, 4] and table["solution"].tolist() == [0] * 6
    np.testing.assert_allclose(table[["q1", "q2", "q3"]].to_numpy(), np.radians(DEGREES), rtol=0, atol=1e-15)
    np.testing.assert_allclose(table[["x", "y", "z"]].to_numpy(), SEEN, rtol=0, atol=1e-15)
    assert str(table["time"].dtype) == "datetime64[ns, UTC]"
    assert table["time"].iloc[1] == pd.Timestamp("2024-05-02T10:00:10Z")
    section = report["sensors"]["laser_tracker"]
    assert section["matched"] == 6 and section["unmatched"] == [] and section["not_measured"] == []
    assert section["marker_not_seen"] == [{"file": str(tmp_path / "tracker.csv"), "line": 5, "key": "P2"}]
    assert json.loads((folder / importer.REPORT_FILE).read_text()) == report


def test_import_is_deterministic_and_refuses_to_overwrite(tmp_path):
    config = write_import(tmp_path)
    folder, _ = folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with pytest.raises(InputError, match="exists already"):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path, overwrite=True)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_match_by_time_lists_the_unmatched_sensor_row(tmp_path):
    tracker = """\
t;x;y;z
2024-05-02T12:00:00.2+02:00;1,5;0;0,02
2024-05-02 10:00:10.4;1,0;0,1;0,2
2024-05-02T10:00:19.7Z;1,1;0,1;0,2
2024-05-02T10:00:45Z;1,2;0,1;0,2
2024-05-02T10:00:40Z;0,9;0,4;-0,1
2024-05-02T10:00:50Z;1,1;-0,3;0,15
"""
    config = write_import(
        tmp_path,
        tracker=tracker,
        sensor={
            "xyz": ["x", "y", "z"],
            "unit": "m",
            "match": "time",
            "key": None,
            "time": "t",
            "tolerance": 0.5,
            "delimiter": ";",
            "decimal": ",",
        },
        controller_section={"time": "stamp", "key": None},
    )
    folder, report = folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    table = folders.read_campaign(folder, repo_root=tmp_path).sensors["laser_tracker"].table
    np.testing.assert_allclose(
        table[["x", "y", "z"]].to_numpy(),
        [[1.5, 0, 0.02], [1.0, 0.1, 0.2], [1.1, 0.1, 0.2], [np.nan] * 3, [0.9, 0.4, -0.1], [1.1, -0.3, 0.15]],
        atol=1e-15,
    )
    assert table["time"].iloc[0] == pd.Timestamp("2024-05-02T10:00:00Z")  # the controller's time
    section = report["sensors"]["laser_tracker"]
    assert section["matched"] == 5 and report["unmatched_rows"] == 1
    [unmatched] = section["unmatched"]
    assert unmatched["file"] == str(tmp_path / "tracker.csv") and unmatched["line"] == 5
    assert unmatched["time"] == "2024-05-02T10:00:45Z" and "nearest 5 s away" in unmatched["reason"]
    assert section["not_measured"] == [
        {"file": str(tmp_path / "controller.csv"), "line": 5, "time": "2024-05-02T10:00:30"}
    ]


def test_two_sensor_rows_near_one_controller_row_keep_the_nearest(tmp_path):
    tracker = (
        "t,x,y,z\n2024-05-02T10:00:00.3,1,0,0\n2024-05-02T10:00:00.1,2,0,0\n2024-05-02T10:00:10,1,1,0\n"
        "2024-05-02T10:00:20,1,0,1\n2024-05-02T10:00:40,1,1,1\n"
    )
    config = write_import(
        tmp_path,
        tracker=tracker,
        sensor={"xyz": ["x", "y", "z"], "unit": "m", "match": "time", "key": None, "time": "t", "tolerance": 1.0},
        controller_section={"time": "stamp", "key": None},
    )
    folder, report = folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    table = folders.read_campaign(folder, repo_root=tmp_path).sensors["laser_tracker"].table
    assert table["x"].iloc[0] == 2.0
    [unmatched] = report["sensors"]["laser_tracker"]["unmatched"]
    assert unmatched["line"] == 2 and "already matched by line 3" in unmatched["reason"]


def test_non_numeric_cell_names_file_line_and_column(tmp_path):
    config = write_import(tmp_path, controller=CONTROLLER.replace("P3,90,0", "P3,90,abc"))
    with pytest.raises(InputError) as error:
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    message = str(error.value)
    assert "controller.csv" in message and "A2" in message and "line 4" in message and "'abc'" in message
    assert not (tmp_path / "raw" / "cell3").exists()


def test_missing_column_is_named(tmp_path):
    config = write_import(tmp_path, tracker=TRACKER.replace("id,X,Y,Z", "id,X,Y,Zmm"))
    with pytest.raises(
        InputError,
        match=r"tracker\.csv: Z: missing column\(s\) \(named by `sensors/laser_tracker/xyz` of the import configuration; got: id, X, Y, Zmm\)",
    ):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)


def test_duplicate_keys_are_named(tmp_path):
    config = write_import(tmp_path, tracker=TRACKER + "P3,1,2,3\n")
    with pytest.raises(InputError, match=r"tracker\.csv: id: duplicate keys .* on lines 2, 9: 'P3', 'P3'"):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)


def test_ragged_row_and_bad_time_name_their_line(tmp_path):
    with pytest.raises(InputError, match=r"c\.csv: line 3 has 2 fields, the header has 3"):
        importer.parse_csv("a,b,c\n1,2,3\n4,5\n", "c.csv")
    config = write_import(
        tmp_path, controller=CONTROLLER.replace("10:00:20", "ten past"), controller_section={"time": "stamp"}
    )
    with pytest.raises(InputError, match=r"controller\.csv: stamp: not a time \(time_format iso\) on line 4"):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)


def test_configuration_errors_name_the_key(tmp_path):
    config = write_import(tmp_path, sensor={"unit": "inch"})
    with pytest.raises(InputError, match="import.yaml: sensors/laser_tracker/unit: must be one of mm, m"):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    config = write_import(tmp_path, controller_section={"joints": ["A1", "A2"]})
    with pytest.raises(InputError, match="controller/joints: names 2 joint columns but the robot has 3"):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    config = write_import(tmp_path, sensor={"match": "time", "tolerance": 0.5}, controller_section={"time": None})
    with pytest.raises(InputError, match="controller/time: missing"):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)


def test_cli_import(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    config = write_import(tmp_path)
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(tmp_path / "raw")]) == 0
    assert "0 unmatched sensor rows" in capsys.readouterr().out
    config = write_import(tmp_path, tracker=TRACKER.replace("1200.25", "12OO.25"))
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(tmp_path / "raw"), "--force"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("remaster import: error: ") and "tracker.csv: X: not a finite number on line 6" in err


@pytest.mark.parametrize("name", ["../escaped", "absolute", "a/b", ".."])
def test_a_name_that_is_not_one_folder_is_refused_and_nothing_is_written(tmp_path, capsys, monkeypatch, name):
    """The name is joined to --raw-dir: '../x' or an absolute name used to put campaign.yaml and the
    Parquet file outside it, then exit 2 saying that nothing was written."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    name = str(tmp_path / "outside") if name == "absolute" else name
    config = write_import(work)
    files.write_yaml(config, {**files.read_yaml(config), "name": name})
    before = sorted(tmp_path.rglob("*"))
    assert cli.main(["import", "--config", str(config), "--raw-dir", str(work / "raw")]) == 2
    err = capsys.readouterr().err
    # the name as messages show a value (`errors.quoted`: a long absolute path shortened)
    assert "import.yaml: name: must be a folder name (one path component" in err and quoted(name) in err
    assert sorted(tmp_path.rglob("*")) == before


def test_the_instruments_mpe_is_kept(tmp_path):
    config = write_import(tmp_path, sensor={"mpe": 2.5e-5})
    folder, _ = folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    assert files.read_yaml(folder / "campaign.yaml")["sensors"]["laser_tracker"]["mpe"] == 2.5e-5
    assert folders.read_campaign(folder, repo_root=tmp_path).sensors["laser_tracker"].mpe == 2.5e-5


def test_contract_check_after_import_names_the_exports(tmp_path):
    """Degrees declared as radians pass the parser but not the campaign reader: the error names
    the controller log's columns and lines, not the staged Parquet file."""
    config = write_import(tmp_path, controller_section={"unit": "rad"})
    with pytest.raises(InputError) as error:
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    message = str(error.value)
    assert message.startswith(str(tmp_path / "controller.csv")) and "A1, A2, A3" in message
    assert "lines 2, 3, 4, 6, 7" in message
    assert "(campaign table laser_tracker)" in message and ".parquet" not in message


def test_urdf_next_to_the_configuration_is_copied_into_the_campaign(tmp_path):
    shutil.copyfile(IIWA_URDF, tmp_path / "arm.urdf")
    joints = [f"A{j}" for j in range(1, 8)]
    rows = [
        [0, 30, 0, -60, 0, 45, 0],
        [20, 40, 0, -80, 10, 30, 0],
        [-30, 50, 0, -40, 0, 60, 0],
        [45, 20, 0, -90, -20, 40, 0],
        [-10, 60, 0, -30, 0, 20, 0],
        [60, 35, 0, -70, 30, 50, 0],
    ]
    controller = (
        "point,"
        + ",".join(joints)
        + "\n"
        + "".join(f"P{i + 1}," + ",".join(map(str, row)) + "\n" for i, row in enumerate(rows))
    )
    tracker = "id,X,Y,Z\n" + "".join(
        f"P{i + 1},{800 + 37 * i},{-200 + 91 * i**2},{500 - 55 * i}\n" for i in range(len(rows))
    )
    config = write_import(
        tmp_path,
        controller=controller,
        tracker=tracker,
        controller_section={"joints": joints, "set": None, "time": None},
    )
    meta = files.read_yaml(config)
    meta["robot"] = {"urdf": "arm.urdf", "base": "iiwa_link_0", "flange": "iiwa_link_ee"}
    files.write_yaml(config, meta)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    folder, _ = folders.import_campaign(config, tmp_path / "raw", repo_root=elsewhere)
    assert (folder / "arm.urdf").read_bytes() == IIWA_URDF.read_bytes()
    campaign = folders.read_campaign(folder, repo_root=elsewhere)
    assert campaign.robot["urdf"] == "arm.urdf" and campaign.n_joints == 7
    assert campaign.sensors["laser_tracker"].table["set"].eq("optimization").all()


def test_a_full_pose_probe_imports_its_orientation_as_a_rotation_vector_or_a_quaternion(tmp_path):
    """A 6-DoF probe's export: the same orientations as a rotation vector in degrees and as unit
    quaternions (w, x, y, z; one given with w < 0, the same rotation) import to the same rotation
    vectors in rad; an empty orientation stays NaN; a quaternion of norm 2 is refused by line."""
    from remaster import spatial

    vectors = np.array([[10.0, -20.0, 5.0], [0.0, 0.0, 0.0], [170.0, 10.0, 0.0], [-30.0, 0.0, 60.0], [1.0, 2.0, 3.0]])
    rotations = spatial.rotation_vector_to_matrix(np.radians(vectors))
    angles = np.linalg.norm(np.radians(vectors), axis=1)
    axes = np.radians(vectors) / np.where(angles > 0, angles, 1.0)[:, None]
    quaternions = np.column_stack([np.cos(angles / 2), np.sin(angles / 2)[:, None] * axes])
    quaternions[3] *= -1.0
    ids = ["P3", "P1", "P4", "P6", "P5"]
    rows = {
        "P3": (1000, -250.5, 300),
        "P1": (1500, 0, 20),
        "P4": (1200.25, 10, 5),
        "P6": (900, 400, -100),
        "P5": (1100, -300, 150),
    }
    probe = {"orientation_noise": 1e-4, "probe_rotation": [0.0, 0.0, 0.0]}
    for name, columns, values, extra in (
        ("vector", ["RX", "RY", "RZ"], vectors, {"orientation_unit": "deg"}),
        ("quaternion", ["QW", "QX", "QY", "QZ"], quaternions, {}),
    ):
        lines = [",".join(["id", "X", "Y", "Z", *columns])]
        lines += [",".join([i, *map(str, rows[i]), *(repr(float(x)) for x in v)]) for i, v in zip(ids, values)]
        lines.append("P2,,,," + "," * (len(columns) - 1))
        root = tmp_path / name
        root.mkdir()
        config = write_import(root, tracker="\n".join(lines) + "\n", sensor={**probe, "orientation": columns, **extra})
        folder, _ = folders.import_campaign(config, root / "raw", repo_root=root)
        sensor = folders.read_campaign(folder, repo_root=root).sensors["laser_tracker"]
        table_rows = [int(i[1]) - 1 for i in ids]  # P1..P6 are the controller's rows 0..5
        np.testing.assert_allclose(sensor.orientations(table_rows), rotations, atol=1e-12)
        assert np.isnan(sensor.orientations([1])).all()  # P2: not seen
    broken = "id,X,Y,Z,QW,QX,QY,QZ\nP1,1500,0,20,2,0,0,0\n"
    config = write_import(tmp_path, tracker=broken, sensor={**probe, "orientation": ["QW", "QX", "QY", "QZ"]})
    with pytest.raises(
        InputError, match=r"tracker.csv: QW, QX, QY, QZ: not a unit quaternion \(w, x, y, z\) on line 2"
    ):
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)


@pytest.mark.parametrize(
    "tracker, section, key, words",
    [
        ("id,X,Y,Z,RX,RY,RZ\nP1,1500,0,20,1,,2\n", {"orientation_unit": "deg"}, "RX, RY, RZ", "some but not all"),
        ("id,X,Y,Z,RX,RY,RZ\nP1,,,,1,2,3\n", {"orientation_unit": "deg"}, "RX, RY, RZ", "a probe measures both"),
        ("id,X,Y,Z,RX,RY,RZ\nP1,1500,0,20,1,2,3\n", {}, "sensors/laser_tracker/orientation_unit", "rad"),
    ],
    ids=["partial", "without a position", "no unit"],
)
def test_a_full_pose_probes_bad_orientation_is_named(tmp_path, tracker, section, key, words):
    probe = {"orientation_noise": 1e-4, "probe_rotation": [0.0, 0.0, 0.0], "orientation": ["RX", "RY", "RZ"]}
    config = write_import(tmp_path, tracker=tracker, sensor={**probe, **section})
    with pytest.raises(InputError) as info:
        folders.import_campaign(config, tmp_path / "raw", repo_root=tmp_path)
    assert info.value.key == key and words in str(info.value)


ROTATION_EXPORT = (  # TRACKER with orientations, P3's (line 3) to fill in
    "id,X,Y,Z,RX,RY,RZ\nP1,1500,0,20,0,0,1\nP3,1000,-250.5,300,{}\nP4,1200.25,10,5,0,0,1\n"
    "P6,900,400,-100,0,0,1\nP5,1100,-300,150,0,0,1\n"
)


def test_a_rotation_vector_beyond_half_a_turn_is_degrees_in_rad_and_kept_in_degrees(tmp_path):
    """A vector of 212 in rad is refused as degrees, naming the export, its columns and its line;
    the same 212 deg with orientation_unit deg is a rotation (it used to be refused as radians, by
    the campaign reader): imported as the same rotation the short way, 148 deg about the opposite
    axis. Beyond a turn even in degrees, or a quaternion off unit norm, is refused by line."""
    from remaster import spatial

    probe = {"orientation_noise": 1e-4, "probe_rotation": [0.0, 0.0, 0.0], "orientation": ["RX", "RY", "RZ"]}
    for name in ("rad", "deg", "turns", "quaternion"):
        (tmp_path / name).mkdir()
    vector = np.array([0.0, 0.6, 0.8]) * 212.0
    tracker = ROTATION_EXPORT.format(",".join(repr(float(v)) for v in vector))
    config = write_import(tmp_path / "rad", tracker=tracker, sensor={**probe, "orientation_unit": "rad"})
    with pytest.raises(InputError) as info:
        folders.import_campaign(config, tmp_path / "rad" / "raw", repo_root=tmp_path)
    assert info.value.file == str(tmp_path / "rad" / "tracker.csv") and info.value.key == "RX, RY, RZ"
    assert "looks like degrees: 212 deg = 3.7 rad (if the export is in degrees, set orientation_unit: deg)" in str(
        info.value
    ) and str(info.value).endswith("(line 3)")
    assert not (tmp_path / "rad" / "raw").exists()

    config = write_import(tmp_path / "deg", tracker=tracker, sensor={**probe, "orientation_unit": "deg"})
    folder, _ = folders.import_campaign(config, tmp_path / "deg" / "raw", repo_root=tmp_path)
    sensor = folders.read_campaign(folder, repo_root=tmp_path).sensors["laser_tracker"]
    np.testing.assert_allclose(sensor.orientations([2])[0], spatial.rotation_vector_to_matrix(np.radians(vector)))
    stored = sensor.table.loc[2, ["rx", "ry", "rz"]].to_numpy(float)
    np.testing.assert_allclose(stored, -np.radians(148.0) * np.array([0.0, 0.6, 0.8]), atol=1e-12)

    for name, row, section, words in (
        ("turns", "0,0,400", {"orientation_unit": "deg"}, "longer than a turn (360 deg) with orientation_unit deg"),
        ("quaternion", "0.5,0.5,0.5,0.6", {"orientation": ["QW", "QX", "QY", "QZ"]}, "not a unit quaternion"),
    ):
        export = ROTATION_EXPORT.replace(",0,0,1\n", ",1,0,0,0\n" if name == "quaternion" else ",0,0,1\n")
        export = export.replace("RX,RY,RZ", "QW,QX,QY,QZ" if name == "quaternion" else "RX,RY,RZ").format(row)
        config = write_import(tmp_path / name, tracker=export, sensor={**probe, **section})
        with pytest.raises(InputError) as info:
            folders.import_campaign(config, tmp_path / name / "raw", repo_root=tmp_path)
        assert info.value.file == str(tmp_path / name / "tracker.csv") and words in str(info.value)
        assert "on line 3" in str(info.value)


def test_a_reader_error_on_orientation_columns_names_the_sensors_export():
    """A problem the campaign reader finds in rx, ry, rz is named in the sensor's export (its
    columns and lines), not in the controller log (it used to name controller.csv)."""
    probe = {"orientation_noise": 1e-4, "probe_rotation": [0.0, 0.0, 0.0], "orientation": ["RX", "RY", "RZ"]}
    for columns, expected in ((["RX", "RY", "RZ"], "RX, RY, RZ"), (["QW", "QX", "QY", "QZ"], "QW, QX, QY, QZ")):
        config = {
            "name": "cell3",
            "date": "2024-05-02",
            "robot": ROBOT,
            "controller": {"file": "controller.csv", "joints": ["A1", "A2", "A3"], "unit": "deg", "key": "point"},
            "sensors": {
                "laser_tracker": {
                    "kind": "laser_tracker",
                    "marker": [-0.1, 0.0, 0.02],
                    "noise": 1e-5,
                    "file": "tracker.csv",
                    "xyz": ["X", "Y", "Z"],
                    "unit": "mm",
                    "match": "key",
                    "key": "id",
                    **probe,
                    "orientation": columns,
                    **({"orientation_unit": "rad"} if len(columns) == 3 else {}),
                }
            },
        }
        spec = importer.parse_config(config, "import.yaml")
        controller = importer.parse_csv("point,A1,A2,A3\nP1,0,0,0\nP2,1,1,1\n", "controller.csv")
        values = "1,0,0,0" if len(columns) == 4 else "0,0,0"
        tracker = importer.parse_csv(f"id,X,Y,Z,{','.join(columns)}\nP2,1,1,1,{values}\n", "tracker.csv")
        result = importer.build_campaign(spec, controller, {"laser_tracker": tracker})
        problem = InputError("a rotation vector longer than pi rad", file="x.parquet", key="rx, ry, rz", rows=[1])
        named = importer.in_exports(problem, "laser_tracker", spec, result, controller, {"laser_tracker": tracker})
        assert str(named) == (
            f"tracker.csv: {expected}: a rotation vector longer than pi rad (campaign table laser_tracker) on line 2"
        )
