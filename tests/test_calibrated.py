"""The calibrated URDF is the calibrated model: Pinocchio's own parser reproduces remaster's
predictions; controller offsets in the controller's units."""

import numpy as np
import pandas as pd
import pinocchio as pin
import pytest

from remaster import blocks, calibrated, kinematics, prediction
from remaster.model import DEG

from .conftest import UR5_URDF

MARKER = np.array([0.03, -0.02, 0.05])


def ur5_urdf_chain():
    return kinematics.chain_from_urdf(UR5_URDF.read_text(), source=str(UR5_URDF))


def pinocchio_points(xml, chain, q):
    """Marker positions (n, 3) in the base frame by Pinocchio from URDF text."""
    model = pin.buildModelFromXML(xml)
    data = model.createData()
    base, flange = model.getFrameId(chain.base_frame), model.getFrameId(chain.flange_frame)
    joints = [model.joints[model.getJointId(name)] for name in chain.joint_names]
    out = []
    for row in q:
        configuration = pin.neutral(model)
        for joint, angle in zip(joints, row):  # a continuous joint is (cos, sin) in Pinocchio
            values = [np.cos(angle), np.sin(angle)] if joint.nq == 2 else [angle]
            configuration[joint.idx_q:joint.idx_q + joint.nq] = values
        pin.framesForwardKinematics(model, data, configuration)
        placement = data.oMf[base].actInv(data.oMf[flange])
        out.append(placement.act(MARKER))
    return np.array(out)


def random_values(chain, rng):
    values = {f"zero_offsets.q{j + 1}": rng.normal(0.0, 0.5 * DEG) for j in range(chain.n_joints)}
    for _, column, name in blocks.link_labels(chain):
        values[name] = rng.normal(0.0, 1e-3 if column == 0 else 0.1 * DEG)
    return values


@pytest.mark.parametrize("robot", ["iiwa", "ur5"])
def test_pinocchio_reads_the_calibrated_urdf_as_the_calibrated_model(robot, iiwa, rng):
    chain = iiwa if robot == "iiwa" else ur5_urdf_chain()
    values = random_values(chain, rng)
    xml, left = calibrated.calibrated_urdf(chain, values)
    q = rng.uniform(np.maximum(chain.lower, -2.5), np.minimum(chain.upper, 2.5), (25, chain.n_joints))
    expected = prediction.robot_points(chain, q, MARKER, values, ("link_geometry",))
    np.testing.assert_allclose(pinocchio_points(xml, chain, q), expected, rtol=0, atol=1e-9)
    # and remaster's own parser agrees: the same link and joint names, a chain it reads again
    again = kinematics.chain_from_urdf(xml, chain.base_frame, chain.flange_frame)
    assert again.joint_names == chain.joint_names
    assert left == []


def test_a_chain_ending_on_a_joint_keeps_its_tool_twist_out_of_the_urdf_and_says_so(iiwa, rng):
    chain = kinematics.chain_from_urdf(iiwa.urdf_xml, "iiwa_link_0", "iiwa_link_7")
    values = random_values(chain, rng)
    xml, left = calibrated.calibrated_urdf(chain, values)
    assert len(left) == 1 and left[0].startswith("link_geometry.tool")
    q = rng.uniform(-1.0, 1.0, (10, chain.n_joints))
    held = {k: v for k, v in values.items() if ".tool." not in k}
    expected = prediction.robot_points(chain, q, MARKER, held, ("link_geometry",))
    np.testing.assert_allclose(pinocchio_points(xml, chain, q), expected, rtol=0, atol=1e-9)


def test_the_nominal_values_give_the_nominal_robot(iiwa, rng):
    xml, _ = calibrated.calibrated_urdf(iiwa, {})
    q = rng.uniform(-1.0, 1.0, (10, iiwa.n_joints))
    np.testing.assert_allclose(pinocchio_points(xml, iiwa, q), prediction.robot_points(iiwa, q, MARKER, {}),
                               rtol=0, atol=1e-12)


def test_controller_offsets_in_degrees_and_radians_with_held_joints_flagged():
    table = pd.DataFrame({"parameter": ["zero_offsets.q1", "zero_offsets.q2"], "mean": [0.0, 0.3 * DEG],
                          "std": [np.nan, 0.01 * DEG], "q2.5": [np.nan, 0.28 * DEG], "q97.5": [np.nan, 0.32 * DEG],
                          "status": ["held: not identifiable", "estimated"]})
    offsets = calibrated.controller_offsets(["a1", "a2"], table, "paper").set_index("joint")
    assert offsets.loc["a2", "correction_deg"] == pytest.approx(0.3)
    assert offsets.loc["a2", "correction_rad"] == pytest.approx(0.3 * DEG)
    assert offsets.loc["a2", "std_deg"] == pytest.approx(0.01)
    assert np.isnan(offsets.loc["a1", "std_deg"]) and offsets.loc["a1", "status"].startswith("held")


def test_a_dh_robot_gets_a_urdf_of_its_own_that_pinocchio_reads_as_calibrated(ur5_dh, rng):
    values = random_values(ur5_dh, rng)
    xml, left = calibrated.calibrated_urdf(ur5_dh, values)
    assert left == []
    q = rng.uniform(-2.5, 2.5, (20, ur5_dh.n_joints))
    expected = prediction.robot_points(ur5_dh, q, MARKER, values, ("link_geometry",))
    np.testing.assert_allclose(pinocchio_points(xml, ur5_dh, q), expected, rtol=0, atol=1e-9)
