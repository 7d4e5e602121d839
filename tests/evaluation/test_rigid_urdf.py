"""rigid.urdf: the rigid chain nearest a loop-closed model with joint compliance, read back by
Pinocchio (a URDF parser remaster did not write), and scored on configurations it was not fitted to."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from remaster.calibration import exports, prediction
from remaster.campaigns.folders import read_campaign
from remaster.evaluation import rigid_urdf
from remaster.evaluation.workspace import fit_domain
from remaster.inference.parameter_blocks import link_labels
from remaster.inference.readings import ModelSettings
from remaster.units import DEG

from ..calibration.test_exports import MARKER, pinocchio_points
from ..conftest import REPO

pin = pytest.importorskip("pinocchio")


@pytest.fixture(scope="module")
def campaign():
    return read_campaign(REPO / "data" / "raw" / "kuka-compliance")


def loop_with(chain, rng, compliance: bool) -> prediction.Calibration:
    """A loop-closed calibration of the iiwa: zero-offsets, link geometry, a marker offset and,
    with `compliance`, joint compliance of 10-40 urad/(N m), as the loop finds on the bundled
    compliant iiwa (some tenths of a millimetre of sag)."""
    values = {f"zero_offsets.q{j + 1}": rng.normal(0.0, 0.2 * DEG) for j in range(chain.n_joints)}
    for _, column, name in link_labels(chain):
        values[name] = rng.normal(0.0, 3e-4 if column < 3 else 0.02 * DEG)
    values |= {"marker_offset.x": 2e-4, "marker_offset.y": -1e-4, "marker_offset.z": 3e-4}
    blocks = ("marker_offset", "link_geometry")
    if compliance:
        values |= {f"joint_compliance.q{j + 1}": rng.uniform(1e-5, 4e-5) for j in range(chain.n_joints)}
        blocks = ("joint_compliance", *blocks)
    return prediction.Calibration("loop", values, blocks, ModelSettings())


def test_the_rigid_urdf_follows_a_compliant_arm_closer_than_its_loop_urdf_and_pinocchio_reads_it(campaign, rng):
    chain = campaign.chain
    loop = loop_with(chain, rng, compliance=True)
    paper = prediction.Calibration("paper", {k: v for k, v in loop.values.items() if k.startswith("zero_offsets")})
    fit = rigid_urdf.rigid_urdf_fit(campaign, "laser_tracker", paper, loop, seed=3)
    far = fit.distances
    # the compliance sags the arm by tenths of a millimetre; loop.urdf alone leaves all of it
    assert 0.05 < far["loop.urdf"]["median_mm"] < 2.0
    # scored on configurations drawn apart from those fitted to: the rigid chain follows most of it
    assert far["rigid.urdf"]["median_mm"] < 0.5 * far["loop.urdf"]["median_mm"]
    assert far["rigid.urdf"]["max_mm"] < far["loop.urdf"]["max_mm"]
    # ik.urdf: the links between the joints nominal, only the zero-offsets, base and tool fitted
    assert all(k.startswith(rigid_urdf.IK_PREFIXES) for k, v in fit.ik_values.items() if v != 0.0)
    assert far["rigid.urdf"]["median_mm"] <= far["ik.urdf"]["median_mm"] < far["paper.urdf"]["median_mm"]
    # the URDF written holds exactly the fitted chain: Pinocchio's forward kinematics of its flange
    xml, left = exports.calibrated_urdf(chain, fit.values)
    assert left == []
    q = rng.uniform(np.maximum(chain.lower, -2.0), np.minimum(chain.upper, 2.0), (20, chain.n_joints))
    expected = prediction.robot_points(chain, q, MARKER, fit.values, ("link_geometry",))
    np.testing.assert_allclose(pinocchio_points(xml, chain, q), expected, rtol=0, atol=1e-9)
    assert fit.report["distance_from_loop_model_mm"] == far and fit.report["configurations"] == fit.configurations


def test_a_loop_model_a_urdf_can_hold_is_its_own_rigid_urdf(campaign, rng):
    """Without effects beyond the joint origins, rigid.urdf is loop.urdf: both at 0 from the loop model."""
    loop = loop_with(campaign.chain, rng, compliance=False)
    fit = rigid_urdf.rigid_urdf_fit(campaign, "laser_tracker", loop, loop, seed=3)
    assert fit.distances["loop.urdf"]["max_mm"] < 1e-9
    assert fit.distances["rigid.urdf"]["max_mm"] < 1e-6


def test_the_rigid_urdf_holds_the_flanges_pose_so_a_tool_off_the_marker_is_as_right(campaign, rng):
    """Fitted to the marker alone, a rigid chain may tilt its flange to absorb what the compliance
    does at the marker; fitted to the flange's whole pose too, it is the nearest URDF to the loop
    model at a tool anywhere on the flange, not only at the marker."""
    tools = {"gripper": np.array([0.1, 0.0, 0.1]), "probe": np.array([0.0, 0.05, 0.2])}
    loop = loop_with(campaign.chain, rng, compliance=True)
    paper = prediction.Calibration("paper", {k: v for k, v in loop.values.items() if k.startswith("zero_offsets")})
    fit = rigid_urdf.rigid_urdf_fit(dataclasses.replace(campaign, tools=tools), "laser_tracker", paper, loop, seed=4)
    assert set(fit.at_tools) == set(tools) and fit.report["tools_m"]["gripper"] == [0.1, 0.0, 0.1]
    for tool, far in fit.at_tools.items():
        nearest = min(far, key=lambda name: far[name]["median_mm"])
        assert nearest == "rigid.urdf", (tool, far)
        # as right at the tool as at the marker (within the compliance's own spread over the flange)
        assert far["rigid.urdf"]["median_mm"] < 1.5 * fit.distances["rigid.urdf"]["median_mm"]
    # the flange's orientation follows the loop model's near the measured configurations
    domain = fit_domain(campaign.chain, campaign.sensors["laser_tracker"])
    q = domain.nearness.draw(50, rng, domain.limits_lower, domain.limits_upper)
    at = prediction.Predictor(campaign.chain, q, MARKER, ("link_geometry",))
    loop_flange = loop.predictor(campaign.chain, q, MARKER).flange_poses(loop.values)
    tilt = [
        np.arccos(np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2, -1, 1))
        for a, b in zip(at.flange_poses(fit.values), loop_flange)
    ]
    # what a rigid chain cannot follow of the compliance's rotation (1.5 mrad); fitted to the marker
    # alone the same chain tilted 31 mrad (1.8 deg) and put these tools 3.5-6.2 mm from the loop model
    assert np.median(tilt) < 3e-3


def test_a_campaign_without_tools_is_scored_at_the_flange_and_150_mm_out(campaign, rng):
    loop = loop_with(campaign.chain, rng, compliance=False)
    fit = rigid_urdf.rigid_urdf_fit(campaign, "laser_tracker", loop, loop, seed=3)
    assert list(fit.at_tools) == list(rigid_urdf.DEFAULT_TOOLS)
    # a loop model a URDF can hold: its own URDFs hold its flange's pose exactly
    out = fit.at_tools["150 mm along the flange axis"]
    assert out["loop.urdf"]["max_mm"] < 1e-9 and out["rigid.urdf"]["max_mm"] < 1e-6
