"""Campaigns of other shapes end to end, in one run: a marker on the last joint's axis and a
full-pose probe. Apart from test_workflow's runs, so the suite's workers run it beside those."""

import re

import numpy as np
import pandas as pd
import pytest

from remaster import files
from remaster.campaigns import folders, scenario, simulation

from ..conftest import REPO
from .conftest import SMALL_FIT, run

pytestmark = pytest.mark.workflow  # runs Snakemake: deselect with -m "not workflow"


def _on_axis(tiny, raw, iiwa):
    """The compliant tiny campaign measured again with the marker on joint 7's axis (its offset moves
    no point)."""
    source = folders.read_campaign(tiny / "raw" / "tiny2")
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-compliance.yaml")
    spec["sensors"]["laser_tracker"]["marker"] = [0.0, 0.0, 0.02]
    rng = np.random.default_rng(7)
    table = source.sensors["laser_tracker"].table.copy()
    q = table[[f"q{j + 1}" for j in range(iiwa.n_joints)]].to_numpy()
    sensor = scenario.sensors_of(spec)["laser_tracker"]
    table[["x", "y", "z"]] = simulation.measure(iiwa, scenario.true_robot(spec, iiwa.n_joints, rng), sensor, q, rng)
    metadata = files.read_yaml(tiny / "raw" / "tiny2" / "campaign.yaml")
    metadata["name"] = "onaxis"
    metadata["sensors"]["laser_tracker"]["marker"] = [0.0, 0.0, 0.02]
    folders.write_campaign(raw / "onaxis", metadata, {"laser_tracker": table})


def _full_pose(raw, iiwa):
    """The bundled full-pose scenario with small sets."""
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-full-pose.yaml")
    spec["name"] = "fullpose"
    spec["plan"]["sets"] = {"optimization": {"configurations": 40}, "validation": {"configurations": 20}}
    out = scenario.simulate(spec, iiwa)
    folders.write_campaign(raw / "fullpose", out.metadata, out.tables)


@pytest.fixture(scope="module")
def shapes(tiny, tmp_path_factory, iiwa):
    """The results folder of one run of both campaigns."""
    root = tmp_path_factory.mktemp("shapes")
    _on_axis(tiny, root / "raw", iiwa)
    _full_pose(root / "raw", iiwa)
    files.write_yaml(
        root / "config.yaml", {"raw_dir": str(root / "raw"), "results_dir": str(root / "results"), **SMALL_FIT}
    )
    # the certificates and what they are made from: figures and the report would add time, not checks
    result = run(root, "--", *(str(root / "results" / name / "certificate.md") for name in ("onaxis", "fullpose")))
    assert result.returncode == 0, result.stderr[-3000:]
    return root / "results"


@pytest.mark.slow  # a real workflow run of minutes
def test_a_campaign_whose_marker_sits_on_the_last_axis_gets_its_certificate(shapes):
    """The on-axis campaign's certificate names what its data cannot tell apart."""
    text = (shapes / "onaxis" / "certificate.md").read_text(encoding="utf-8")
    assert "zero_offsets.q7 is held at the controller's value: 1 deg of it changes no measured point" in text
    assert "| iiwa_joint_7 |  |  |  |  |  | held: not identifiable |" in text


@pytest.mark.slow  # a real workflow run of minutes
def test_a_full_pose_campaign_runs_end_to_end_and_its_certificate_says_what_orientation_added(shapes):
    """Its probe sits on joint 7's axis, so its points alone cannot see joint 7's zero-offset; the
    certificate says the orientations determine it, and the zero-offset model's correction of joint 7
    is estimated, not held."""
    text = (shapes / "fullpose" / "certificate.md").read_text(encoding="utf-8")
    assert re.search(r"a full-pose probe, \d+ orientations fitted beside the points", text)
    assert "they determine the zero-offset of q7, which the points alone leave undetermined" in text
    corrections = pd.read_csv(shapes / "fullpose" / "tables" / "certificate_corrections.csv")
    joint7 = corrections[corrections["Joint"] == "iiwa_joint_7"].set_index("Model")["Status"]
    assert joint7.str.startswith("held").tolist() == [True, False]  # the loop's (points alone), the zero-offsets'
    assert "which the orientations determine" in joint7.iloc[0]
    # the loop-closed calibration carries the orientations' joint-7 offset (loop.urdf, the controller's offsets)
    offsets = pd.read_csv(next((shapes / "fullpose").glob("*/calibrated/controller_offsets.csv")))
    joint7 = offsets[offsets["joint"] == "iiwa_joint_7"].set_index("model")["correction_deg"]
    assert joint7["loop"] == pytest.approx(joint7["paper"], abs=0.02) and abs(joint7["paper"] - 0.936) < 0.1
