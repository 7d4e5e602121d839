"""The UR kinematics_config, loaded as UR users load it: a URDF built from it the way
ur_description's xacro builds one (base_link, base_link_inertia turned by pi, six joints each with
its origin from the file and an axis z, then wrist_3_link, flange and tool0), read by Pinocchio, a
parser remaster did not write, against remaster's own calibrated prediction."""

import numpy as np
import pinocchio as pin
import pytest

from remaster.calibration import prediction, ur_kinematics
from remaster.campaigns.arm_kinds import UR5_DH
from remaster.inference.parameter_blocks import link_labels
from remaster.robot import kinematics
from remaster.units import DEG

MARKER = np.array([0.0, 0.0, 0.031])
JOINT_NAMES = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
LINKS = ("base_link_inertia", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link")


def _joint(name, parent, child, kind, origin, axis=True):
    xyz = " ".join(repr(origin[k]) for k in ("x", "y", "z"))
    rpy = " ".join(repr(origin[k]) for k in ("roll", "pitch", "yaw"))
    limit = '<axis xyz="0 0 1"/><limit lower="-6.28" upper="6.28" effort="1" velocity="1"/>' if axis else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/>{limit}</joint>'
    )


def ur_description_urdf(config: dict) -> str:
    """The URDF ur_description's xacro makes of a kinematics_config (its frames, not its meshes)."""
    kinematics_ = config["kinematics"]
    fixed = {k: 0.0 for k in ("x", "y", "z", "roll", "pitch", "yaw")}
    links = ("base_link", *LINKS, "wrist_3_link", "flange", "tool0")
    parts = [f'<link name="{link}"/>' for link in links]
    parts.append(
        _joint("base_link-base_link_inertia", "base_link", "base_link_inertia", "fixed", {**fixed, "yaw": np.pi}, False)
    )
    chain = (*LINKS, "wrist_3_link")
    for j, (name, key) in enumerate(zip(JOINT_NAMES, ur_kinematics.UR_JOINTS)):
        parts.append(_joint(f"{name}_joint", chain[j], chain[j + 1], "revolute", kinematics_[key]))
    parts.append(
        _joint(
            "wrist_3-flange",
            "wrist_3_link",
            "flange",
            "fixed",
            {**fixed, "pitch": -np.pi / 2, "yaw": -np.pi / 2},
            False,
        )
    )
    parts.append(
        _joint("flange-tool0", "flange", "tool0", "fixed", {**fixed, "roll": np.pi / 2, "yaw": np.pi / 2}, False)
    )
    return f'<robot name="ur">{"".join(parts)}</robot>'


def loaded_points(config: dict, q) -> np.ndarray:
    """Marker positions (n, 3) in base_link_inertia (the DH base) by Pinocchio from that URDF."""
    model = pin.buildModelFromXML(ur_description_urdf(config))
    data = model.createData()
    base, wrist = model.getFrameId("base_link_inertia"), model.getFrameId("wrist_3_link")
    out = []
    for row in q:
        pin.framesForwardKinematics(model, data, np.asarray(row, dtype=float))
        out.append(data.oMf[base].actInv(data.oMf[wrist]).act(MARKER))
    return np.array(out)


def _values(chain, rng, tool: bool) -> dict:
    values = {f"zero_offsets.q{j + 1}": rng.normal(0.0, 0.5 * DEG) for j in range(chain.n_joints)}
    for frame, column, name in link_labels(chain):
        if frame < chain.n_joints or tool:
            values[name] = rng.normal(0.0, 1e-3 if column < 3 else 0.1 * DEG)
    return values


@pytest.mark.parametrize("tool", [False, True], ids=["joints", "joints and tool"])
def test_the_kinematics_config_loaded_as_ur_description_does_is_the_calibrated_model(tool):
    rng = np.random.default_rng(8)
    chain = kinematics.chain_from_dh(UR5_DH, "standard", name="ur5")
    values = _values(chain, rng, tool)
    q = rng.uniform(-np.pi, np.pi, (40, 6))
    config = ur_kinematics.kinematics_config(chain, values, q, MARKER, "test")
    assert set(config["kinematics"]) == {*ur_kinematics.UR_JOINTS, "hash"}
    expected = prediction.robot_points(chain, q, MARKER, values, ("link_geometry",))
    error = np.linalg.norm(loaded_points(config, q) - expected, axis=1)
    remaining = config["remaining"]
    if not tool:
        assert error.max() < 1e-9  # a chain of joint errors alone: the file holds all of it
        assert remaining["max_marker_error_mm"] < 1e-9 and remaining["tool_translation_mm"] < 1e-9
    else:
        # a tool shifted across the last axis and tilted: the file holds its part along and about
        # the axis, and says what it leaves, which is what the loaded description misses by
        assert remaining["tool_translation_mm"] > 0.1
        assert np.isclose(error.max() * 1e3, remaining["max_marker_error_mm"], rtol=1e-6)
        assert error.max() < np.linalg.norm([1.0, 1.0]) * 3e-3  # the shift across the axis, not more


def test_a_chain_of_another_form_has_no_kinematics_config(iiwa):
    assert not ur_kinematics.applies(iiwa)
    with pytest.raises(ValueError, match="six joints turning about z"):
        ur_kinematics.origins(iiwa, {})
