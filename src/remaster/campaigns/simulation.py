"""The world a simulated campaign comes from: a true robot and sensors that measure it.

The true robot is the nominal chain plus true zero-offsets plus optional effects that the
paper's model lacks: joint compliance under gravity, link-geometry errors, a marker-offset
error, a sensor scale error, joint gear-ratio (scale) errors and a slow drift of the
zero-offsets over the campaign's time. The controller reports what the robot believes (the
readings); the true joint angles are

    q_true = (1 + s_j) q_reading + dtheta_j + rate_j * t + c_j * tau_gravity_j(q)

and a sensor at pose T_NR measures (1 + scale) T_NR p_marker(q_true) + noise in its own frame.
The ground truth goes to a separate file that the pipeline never reads.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import spatial
from ..robot.gravity import gravity_torques
from ..robot.kinematics import ForwardKinematics, KinematicChain, perturbed_chain  # noqa: F401 (re-exported)


@dataclass(frozen=True)
class TrueRobot:
    """What the robot really is. Angles in rad, lengths in m, compliance in rad/(N m), drift in
    rad/s; arrays of shape (N,) unless stated; None means the effect is absent."""

    zero_offsets: np.ndarray
    joint_compliance: np.ndarray | None = None
    payload_mass: float = 0.0
    payload_com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    link_errors: np.ndarray | None = None  # (N + 1, 2): length (m) and twist (rad) errors of F_1..F_N, F_tool
    joint_scale: np.ndarray | None = None
    drift_rate: np.ndarray | None = None
    cyclic_error: np.ndarray | None = None  # (N, 3): amplitude (rad), cycles per turn, phase (rad) of a gear's error


@dataclass(frozen=True)
class Sensor:
    """A 3D sensor in the room: its pose in the robot frame (robot <- sensor, 4x4), per-axis
    noise (m), scale error (dimensionless), the nominal marker (3,) in the flange frame and the
    error of that marker's true position (3,). transverse_growth_per_m: 0 for isotropic noise;
    otherwise `noise` is a tracker's range std and its transverse std is noise sqrt(1 + (g d)^2)
    at distance d from the sensor (`remaster.noise`)."""

    name: str
    kind: str
    pose_in_robot: np.ndarray
    noise: float
    marker: np.ndarray
    marker_error: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_error: float = 0.0
    transverse_growth_per_m: float = 0.0

    @property
    def robot_to_sensor(self) -> np.ndarray:
        """T_NR (4, 4): robot-frame points into the sensor frame."""
        return spatial.invert(self.pose_in_robot)


def looking_at(position, target) -> np.ndarray:
    """Sensor pose (robot <- sensor) at `position` with its z axis towards `target` and its x
    axis horizontal."""
    position = np.asarray(position, dtype=float)
    z = np.asarray(target, dtype=float) - position
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    return spatial.homogeneous(np.column_stack([x, np.cross(z, x), z]), position)


def true_joint_angles(chain: KinematicChain, robot: TrueRobot, q_readings, elapsed_s=None) -> np.ndarray:
    """True joint angles (n, N) for controller readings (n, N) at times `elapsed_s` (n,) s."""
    q = np.asarray(q_readings, dtype=float)
    true = q * (1.0 + robot.joint_scale) if robot.joint_scale is not None else q.copy()
    true = true + robot.zero_offsets
    if robot.cyclic_error is not None:
        # a transmission's kinematic error, periodic in the joint's own angle: in no candidate's family
        amplitude, cycles, phase = robot.cyclic_error.T
        true = true + amplitude * np.sin(cycles * q + phase)
    if robot.drift_rate is not None:
        if elapsed_s is None:
            raise ValueError("a drifting robot needs the time of each reading")
        true = true + np.asarray(elapsed_s, dtype=float)[:, None] * robot.drift_rate
    if robot.joint_compliance is not None:
        true_chain = perturbed_chain(chain, robot.link_errors) if robot.link_errors is not None else chain
        tau = gravity_torques(true_chain, true, robot.payload_mass, robot.payload_com)
        true = true + robot.joint_compliance * tau
    return true


def true_marker_positions(
    chain: KinematicChain, robot: TrueRobot, sensor: Sensor, q_readings, elapsed_s=None
) -> np.ndarray:
    """Where the sensor's marker really is, in the robot frame (n, 3)."""
    true_chain = perturbed_chain(chain, robot.link_errors) if robot.link_errors is not None else chain
    q_true = true_joint_angles(chain, robot, q_readings, elapsed_s)
    return ForwardKinematics(true_chain, q_true).points(sensor.marker + sensor.marker_error)


def measure(
    chain: KinematicChain, robot: TrueRobot, sensor: Sensor, q_readings, rng: np.random.Generator, elapsed_s=None
) -> np.ndarray:
    """The sensor's readings (n, 3) in its own frame, noise included."""
    p_sensor = true_sensor_positions(chain, robot, sensor, q_readings, elapsed_s)
    draw = rng.normal(0.0, sensor.noise, p_sensor.shape)
    if sensor.transverse_growth_per_m == 0.0:
        return p_sensor + draw
    u = p_sensor / np.linalg.norm(p_sensor, axis=1, keepdims=True)
    along = np.sum(draw * u, axis=1, keepdims=True) * u
    ratio = np.sqrt(1.0 + (sensor.transverse_growth_per_m * np.linalg.norm(p_sensor, axis=1, keepdims=True)) ** 2)
    return p_sensor + along + ratio * (draw - along)


def true_sensor_positions(
    chain: KinematicChain, robot: TrueRobot, sensor: Sensor, q_readings, elapsed_s=None
) -> np.ndarray:
    """Where the sensor's marker really is, in the sensor's frame as a noiseless sensor reads it (n, 3)."""
    p_robot = true_marker_positions(chain, robot, sensor, q_readings, elapsed_s)
    return (1.0 + sensor.scale_error) * spatial.transform_points(sensor.robot_to_sensor, p_robot)
