"""A calibration as Universal Robots' `kinematics_config`: the YAML that the UR ROS driver and
`ur_description` load (the form `ur_calibration` writes), so that one calibration flows into the
tools UR users run.

`ur_description` builds the arm from six joint origins, each x y z roll pitch yaw (URDF's
fixed-axis convention, R = Rz(yaw) Ry(pitch) Rx(roll)) followed by a rotation about the joint's z
axis, between its base_link_inertia and wrist_3_link frames; what follows (flange, tool0) is fixed
by the description. A chain whose six joints all turn about their frames' z axes (a standard DH
table, or a URDF written that way) maps onto it joint by joint: origin j is the calibrated fixed
transform before joint j with its zero-offset folded in (`parameter_blocks.calibrated_transforms`: a robot
commanded to q is where the calibrated model says), so the frames are remaster's base frame and, as
wrist_3_link, its flange frame. What the calibrated model puts after the last joint (a UR's d6)
moves in front of it where it commutes with the joint (a translation along its axis and a rotation
about it); a calibrated tool transform's remainder (a shift across the axis, a tilt) has no place in the file: `remaining`
gives its size and the largest marker error it leaves at the campaign's configurations.

The `hash` entry is the file's own, not the robot controller's calibration checksum: the driver
warns that they differ, rightly, since the calibration is not the controller's.

SI inside (m, rad), and in the file as `ur_description` takes it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .. import spatial
from ..inference.parameter_blocks import calibrated_transforms
from ..robot.kinematics import KinematicChain

UR_JOINTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
Z = np.array([0.0, 0.0, 1.0])


def applies(chain: KinematicChain) -> bool:
    """Whether the chain has the form a kinematics_config holds: six joints, each turning about its
    own frame's z axis."""
    return chain.n_joints == len(UR_JOINTS) and bool(np.allclose(chain.joint_axes, Z, atol=1e-12))


def _origin(transform: np.ndarray) -> dict[str, float]:
    yaw, pitch, roll = spatial.matrix_to_euler_zyx(transform[:3, :3])
    values = dict(zip(("x", "y", "z", "roll", "pitch", "yaw"), (*transform[:3, 3], roll, pitch, yaw)))
    return {k: float(v) + 0.0 for k, v in values.items()}  # + 0.0: no -0.0 in the file


def origins(chain: KinematicChain, values: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(the six joint origins (6, 4, 4) of the calibrated model `values` {parameter: SI} as a
    kinematics_config holds them, the remainder (4, 4) of its tool transform that none can hold:
    identity when the tool transform is a shift along and a turn about the last axis, as a UR's
    nominal d6 is)."""
    if not applies(chain):
        raise ValueError(f"{chain.name}: a kinematics_config holds six joints turning about z, not this chain")
    joints, tool = calibrated_transforms(chain, values)
    # the tool's part along and about the last joint's axis commutes with the joint's rotation:
    # it moves in front of it, into the last origin, and wrist_3_link is remaster's flange frame
    turn = np.arctan2(tool[1, 0] - tool[0, 1], tool[0, 0] + tool[1, 1])
    movable = spatial.translation(z=float(tool[2, 3])) @ spatial.homogeneous(spatial.rot_z(turn))
    out = np.array(joints)
    out[-1] = out[-1] @ movable
    return out, spatial.invert(movable) @ tool


def kinematics_config(chain: KinematicChain, values: Mapping[str, float], q, marker, label: str) -> dict:
    """The kinematics_config of the calibrated model `values`, with what it cannot hold: the tool
    transform's remainder (translation mm, tilt deg) and the largest marker error (mm) it leaves at
    the configurations q (n, 6) rad, marker (3,) m in the flange frame. label: the file's hash entry
    (campaign, sensor, model)."""
    joints, remainder = origins(chain, values)
    fk = flange_poses(joints, q)
    marker = np.asarray(marker, dtype=float)
    held = spatial.transform_points(fk, marker)
    exact = spatial.transform_points(fk @ remainder, marker)
    error = float(np.max(np.linalg.norm(exact - held, axis=-1))) if len(held) else 0.0
    return {
        "kinematics": {name: _origin(t) for name, t in zip(UR_JOINTS, joints)} | {"hash": f"remaster {label}"},
        "remaining": {
            "tool_translation_mm": float(np.linalg.norm(remainder[:3, 3]) * 1e3),
            "tool_tilt_deg": float(np.degrees(spatial.rotation_angle(remainder[:3, :3]))),
            "max_marker_error_mm": error * 1e3,
            "configurations": int(len(held)),
            "note": "what the calibrated tool transform holds beyond a shift along and a turn about the last joint's "
            "axis: a kinematics_config has no place for it",
        },
    }


def flange_poses(joints: np.ndarray, q) -> np.ndarray:
    """wrist_3_link poses (n, 4, 4) of the chain origin_1 Rz(q1) ... origin_6 Rz(q6) at q (n, 6)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    poses = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    for j in range(joints.shape[0]):
        poses = poses @ joints[j] @ spatial.homogeneous(spatial.rot_z(q[:, j]))
    return poses
