"""Campaigns of other shapes end to end: a marker on the last joint's axis beside two ordinary
campaigns, and a full-pose probe. Each in its own run, apart from test_workflow's runs, so the
suite's workers run them beside those."""

import re
import shutil

import pytest

from remaster import files
from remaster.campaigns import folders, scenario, simulation

from ..conftest import REPO
from .conftest import SMALL_FIT, run

pytestmark = pytest.mark.workflow  # runs Snakemake: deselect with -m "not workflow"


def test_a_campaign_whose_marker_sits_on_the_last_axis_gets_its_certificate_beside_two_others(tiny, tmp_path, iiwa):
    """The compliant tiny campaign measured again with the marker on joint 7's axis (its offset moves
    no point): in one run with the two tiny campaigns, every campaign gets its certificate, and the
    on-axis one names what its data cannot tell apart."""
    import numpy as np

    shutil.copytree(tiny / "raw", tmp_path / "raw")  # copy2: the time stamps too, so tiny's results still hold
    if (tiny / "results").is_dir():
        shutil.copytree(tiny / "results", tmp_path / "results")
    source = folders.read_campaign(tmp_path / "raw" / "tiny2")
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-compliance.yaml")
    spec["sensors"]["laser_tracker"]["marker"] = [0.0, 0.0, 0.02]
    rng = np.random.default_rng(7)
    table = source.sensors["laser_tracker"].table.copy()
    q = table[[f"q{j + 1}" for j in range(iiwa.n_joints)]].to_numpy()
    sensor = scenario.sensors_of(spec)["laser_tracker"]
    table[["x", "y", "z"]] = simulation.measure(iiwa, scenario.true_robot(spec, iiwa.n_joints, rng), sensor, q, rng)
    metadata = files.read_yaml(tmp_path / "raw" / "tiny2" / "campaign.yaml")
    metadata["name"] = "onaxis"
    metadata["sensors"]["laser_tracker"]["marker"] = [0.0, 0.0, 0.02]
    folders.write_campaign(tmp_path / "raw" / "onaxis", metadata, {"laser_tracker": table})
    files.write_yaml(
        tmp_path / "config.yaml",
        {
            **files.read_yaml(tiny / "config.yaml"),
            "raw_dir": str(tmp_path / "raw"),
            "results_dir": str(tmp_path / "results"),
        },
    )
    result = run(tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    for name in ("tiny", "tiny2", "onaxis"):
        assert (tmp_path / "results" / name / "certificate.md").is_file()
    text = (tmp_path / "results" / "onaxis" / "certificate.md").read_text(encoding="utf-8")
    assert "zero_offsets.q7 is held at the controller's value: 1 deg of it changes no measured point" in text
    assert "| iiwa_joint_7 |  |  |  |  | held: not identifiable |" in text


def test_a_full_pose_campaign_runs_end_to_end_and_its_certificate_says_what_orientation_added(tmp_path, iiwa):
    """The bundled full-pose scenario with small sets: its probe sits on joint 7's axis, so its
    points alone cannot see joint 7's zero-offset; the certificate says the orientations determine
    it, and the zero-offset model's correction of joint 7 is estimated, not held."""
    import pandas as pd

    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-full-pose.yaml")
    spec["name"] = "fullpose"
    spec["plan"]["sets"] = {"optimization": {"configurations": 40}, "validation": {"configurations": 20}}
    out = scenario.simulate(spec, iiwa)
    folders.write_campaign(tmp_path / "raw" / "fullpose", out.metadata, out.tables)
    files.write_yaml(
        tmp_path / "config.yaml",
        {"raw_dir": str(tmp_path / "raw"), "results_dir": str(tmp_path / "results"), **SMALL_FIT},
    )
    result = run(tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    text = (tmp_path / "results" / "fullpose" / "certificate.md").read_text(encoding="utf-8")
    assert re.search(r"a full-pose probe, \d+ orientations fitted beside the points", text)
    assert "they determine the zero-offset of q7, which the points alone leave undetermined" in text
    corrections = pd.read_csv(tmp_path / "results" / "fullpose" / "tables" / "certificate_corrections.csv")
    joint7 = corrections[corrections["Joint"] == "iiwa_joint_7"].set_index("Model")["Status"]
    assert joint7.str.startswith("held").tolist() == [True, False]  # the loop's (points alone), the zero-offsets'
    assert "which the orientations determine" in joint7.iloc[0]
    # the loop-closed calibration carries the orientations' joint-7 offset (loop.urdf, the controller's offsets)
    offsets = pd.read_csv(next((tmp_path / "results" / "fullpose").glob("*/calibrated/controller_offsets.csv")))
    joint7 = offsets[offsets["joint"] == "iiwa_joint_7"].set_index("model")["correction_deg"]
    assert joint7["loop"] == pytest.approx(joint7["paper"], abs=0.02) and abs(joint7["paper"] - 0.936) < 0.1
