"""Gravity torques: sign, payload and a hand-computed case."""

import numpy as np

from remaster.robot import kinematics
from remaster.robot.gravity import STANDARD_GRAVITY, gravity_torques


def test_point_mass_on_horizontal_arm():
    """One joint about y, a 2 kg payload 0.5 m out along x: gravity pulls it down, torque m g l about +y."""
    arm = kinematics.KinematicChain(
        name="arm",
        joint_names=("j",),
        joint_transforms=np.eye(4)[None],
        joint_axes=np.array([[0.0, 1.0, 0.0]]),
        tool_transform=np.array([[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]),
        lower=np.array([-np.inf]),
        upper=np.array([np.inf]),
    )
    tau = gravity_torques(arm, np.zeros((1, 1)), payload_mass=2.0)
    # r x F = (0.5, 0, 0) x (0, 0, -2 g) = (0, +g, 0)
    np.testing.assert_allclose(tau, [[2.0 * STANDARD_GRAVITY * 0.5]], rtol=1e-12)
    np.testing.assert_allclose(gravity_torques(arm, [[np.pi / 2]], payload_mass=2.0), 0.0, atol=1e-12)


def test_iiwa_payload_on_vertical_axis_adds_nothing_elsewhere_it_does(iiwa, rng):
    upright = np.zeros((1, 7))
    np.testing.assert_allclose(
        gravity_torques(iiwa, upright, payload_mass=1.0) - gravity_torques(iiwa, upright), 0.0, atol=1e-9
    )
    q = rng.uniform(iiwa.lower, iiwa.upper, (5, 7))
    bare = gravity_torques(iiwa, q)
    loaded = gravity_torques(iiwa, q, payload_mass=1.5, payload_com=[0.0, 0.0, 0.02])
    assert bare.shape == (5, 7)
    assert np.abs(loaded - bare).max() > 0.1
