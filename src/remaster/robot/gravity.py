"""Joint torques exerted by gravity, computed by Pinocchio from the chain's mass properties.

They drive joint compliance: a joint of compliance c (rad/(N m)) deflects by c * tau, where tau
is the torque gravity exerts on it (the negative of the torque the motor must supply to hold).
"""

from __future__ import annotations

import numpy as np

from .kinematics import KinematicChain, pinocchio_model

STANDARD_GRAVITY = 9.80665  # m/s^2


def gravity_torques(
    chain: KinematicChain,
    q,
    payload_mass: float = 0.0,
    payload_com=(0.0, 0.0, 0.0),
    gravity=(0.0, 0.0, -STANDARD_GRAVITY),
) -> np.ndarray:
    """Torques (n, N) in N m that gravity exerts on each joint at configurations q (n, N).

    payload_mass (kg) at payload_com (m, in the flange frame) models a tool plate. The base
    frame's z axis points up unless `gravity` says otherwise. A chain without mass data (a DH
    table) feels the payload only.
    """
    import pinocchio as pin

    q = np.atleast_2d(np.asarray(q, dtype=float))
    model = pinocchio_model(chain)
    model.gravity.linear = np.asarray(gravity, dtype=float)
    if payload_mass > 0.0:
        com = chain.tool_transform[:3, :3] @ np.asarray(payload_com, dtype=float) + chain.tool_transform[:3, 3]
        model.appendBodyToJoint(chain.n_joints, pin.Inertia(payload_mass, com, np.zeros((3, 3))), pin.SE3.Identity())
    data = model.createData()
    return -np.array([pin.computeGeneralizedGravity(model, data, qi) for qi in q]).reshape(len(q), chain.n_joints)
