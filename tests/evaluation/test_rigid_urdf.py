"""rigid.urdf: the rigid chain nearest a loop-closed model with joint compliance, read back by
Pinocchio (a URDF parser remaster did not write), and scored on configurations it was not fitted to."""

from __future__ import annotations

import numpy as np
import pytest

from remaster.calibration import exports, prediction
from remaster.campaigns.folders import read_campaign
from remaster.evaluation import rigid_urdf
from remaster.inference.blocks import ModelSettings, link_labels
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
