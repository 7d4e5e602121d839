"""The console script: `remaster plan` and `remaster simulate` write what they say, and bad input
ends with a named error and exit status 2."""

import numpy as np
import pandas as pd
import pytest

from remaster import DISTRIBUTION, cli, files
from remaster.campaigns import folders
from remaster.robot import kinematics

from .conftest import IIWA_URDF, REPO


def test_plan_writes_commandable_configurations(tmp_path, iiwa):
    out = tmp_path / "plan.csv"
    status = cli.main(
        [
            "plan",
            "--urdf",
            str(IIWA_URDF),
            "--base",
            "iiwa_link_0",
            "--flange",
            "iiwa_link_ee",
            "--sensor-origin",
            "1.6",
            "0.5",
            "1.0",
            "--marker",
            "-0.1",
            "0",
            "0.02",
            "--candidates",
            "20",
            "--seed",
            "3",
            "--out",
            str(out),
        ]
    )
    assert status == 0
    table = pd.read_csv(out)
    q = table[[f"q{j}" for j in range(1, 8)]].to_numpy()
    assert len(table) > 10 and np.all(iiwa.within_limits(q))
    np.testing.assert_allclose(np.radians(table[[f"q{j}_deg" for j in range(1, 8)]].to_numpy()), q, atol=1e-12)
    assert set(table["set"]) == {"optimization"}


def test_plan_from_three_registration_points(tmp_path, iiwa):
    """The sensor origin comes from a three-point registration of measured configurations."""
    sensor_origin = np.array([1.6, 0.5, 1.0])
    q = np.radians([[-40, 40, 0, -70, 0, 50, 0], [0, 20, 0, -100, 0, -30, 0], [40, 55, 0, -40, 0, 60, 0]])
    marker = np.array([-0.1, 0.0, 0.02])
    measured = kinematics.marker_positions(iiwa, q, marker) - sensor_origin  # a sensor frame parallel to the base
    points = pd.DataFrame(q, columns=[f"q{j}" for j in range(1, 8)]).assign(
        x=measured[:, 0], y=measured[:, 1], z=measured[:, 2]
    )
    points.to_csv(tmp_path / "three.csv", index=False)
    common = [
        "plan",
        "--urdf",
        str(IIWA_URDF),
        "--flange",
        "iiwa_link_ee",
        "--marker",
        *map(str, marker),
        "--candidates",
        "10",
    ]
    assert (
        cli.main(common + ["--registration-points", str(tmp_path / "three.csv"), "--out", str(tmp_path / "a.csv")]) == 0
    )
    assert cli.main(common + ["--sensor-origin", *map(str, sensor_origin), "--out", str(tmp_path / "b.csv")]) == 0
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "a.csv"), pd.read_csv(tmp_path / "b.csv"), atol=1e-9)


def test_plan_errors_name_the_problem(tmp_path, capsys):
    status = cli.main(
        [
            "plan",
            "--urdf",
            str(IIWA_URDF),
            "--flange",
            "tool0",
            "--sensor-origin",
            "1",
            "0",
            "1",
            "--out",
            str(tmp_path / "p.csv"),
        ]
    )
    assert status == 2
    assert "robot/flange" in capsys.readouterr().err and not (tmp_path / "p.csv").exists()


def test_simulate_regenerates_a_campaign_that_reads(tmp_path, monkeypatch):
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-compliance.yaml")
    spec["plan"]["sets"] = {
        "optimization": {"poses": 4, "configurations": 15},
        "validation": {"poses": 2, "configurations": 6},
    }
    files.write_yaml(tmp_path / "small.yaml", spec)
    monkeypatch.chdir(REPO)  # the scenario names the robot relative to the repository
    assert (
        cli.main(
            [
                "simulate",
                str(tmp_path / "small.yaml"),
                "--raw-dir",
                str(tmp_path / "raw"),
                "--truth-dir",
                str(tmp_path / "truth"),
            ]
        )
        == 0
    )
    campaign = folders.read_campaign(tmp_path / "raw" / "kuka-compliance", repo_root=REPO)
    assert len(campaign.sensors["laser_tracker"].table) >= 15
    assert (tmp_path / "truth" / "kuka-compliance.json").is_file()


def test_simulate_refuses_no_copies_and_a_name_outside_its_folder(tmp_path, capsys, monkeypatch):
    """--copies 0 used to exit 0 having written nothing; a scenario named '../x' would write its
    campaign beside --raw-dir and its truth beside --truth-dir."""
    monkeypatch.chdir(REPO)
    scenario = REPO / "data" / "simulation" / "kuka-compliance.yaml"
    outputs = ["--raw-dir", str(tmp_path / "sim" / "raw"), "--truth-dir", str(tmp_path / "sim" / "truth")]
    with pytest.raises(SystemExit) as exited:
        cli.main(["simulate", str(scenario), "--copies", "0", *outputs])
    assert exited.value.code == 2
    assert "argument --copies: must be at least 1, got 0" in capsys.readouterr().err
    spec = files.read_yaml(scenario)
    files.write_yaml(tmp_path / "escaping.yaml", {**spec, "name": "../escaped"})
    assert cli.main(["simulate", str(tmp_path / "escaping.yaml"), *outputs]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'escaping.yaml'}: name: must be a folder name" in err and "'../escaped'" in err
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["escaping.yaml"]


def test_version_prints_the_installed_version(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as done:
        cli.main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"remaster {version(DISTRIBUTION)}"


@pytest.mark.slow
def test_a_wheel_installs_the_remaster_command_under_a_free_distribution_name(tmp_path):
    """`pip wheel .` builds remaster-robot (the index's `remaster` is another project), whose entry
    point is the `remaster` command and which carries the paper's published numbers."""
    import shutil
    import subprocess
    import sys
    import zipfile

    source = tmp_path / "source"  # a copy: the build leaves its build/ folder there, not in the checkout
    shutil.copytree(REPO / "src", source / "src", ignore=shutil.ignore_patterns("*.egg-info", "__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, source / name)
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp_path), "."],
        cwd=source,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert built.returncode == 0, built.stderr[-2000:]
    (wheel,) = tmp_path.glob("*.whl")
    assert wheel.name.startswith("remaster_robot-")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        info = next(n for n in names if n.endswith(".dist-info/METADATA"))
        entry = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
        assert "Name: remaster-robot" in archive.read(info).decode()
        assert "remaster = remaster.cli:main" in archive.read(entry).decode()
    assert "remaster/data/paper_values.csv" in names and "remaster/cli.py" in names
    assert "remaster/data/config.schema.yaml" in names  # the schema `remaster.configuration.settings` reads


def test_long_commands_tell_a_terminal_what_they_do_and_nothing_else(monkeypatch):
    """While a command runs on a terminal, what the library logs goes to standard error at most every
    PROGRESS_EVERY seconds (warnings always); piped or logged, nothing; the handler goes with the command."""
    import io
    import logging

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    library = logging.getLogger("remaster.calibration.compensation")
    terminal = Terminal()
    monkeypatch.setattr(cli.sys, "stderr", terminal)
    with cli._progress("compensate"):
        library.info("%d targets: inverse kinematics on the nominal model", 40)
        library.info("%d commands: inverse kinematics on the calibrated model", 38)  # within PROGRESS_EVERY
        library.warning("a warning is always shown")
    library.info("after the command: not shown")
    assert terminal.getvalue().splitlines() == [
        "remaster compensate: 40 targets: inverse kinematics on the nominal model",
        "remaster compensate: a warning is always shown",
    ]
    piped = io.StringIO()
    monkeypatch.setattr(cli.sys, "stderr", piped)
    with cli._progress("compensate"):
        library.info("not shown")
    assert piped.getvalue() == ""
