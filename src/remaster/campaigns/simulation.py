"""The world a simulated campaign comes from: a true robot and sensors that measure it.

The true robot is the nominal chain plus true zero-offsets plus optional effects that the
paper's model lacks: joint compliance under gravity, link-geometry errors, a marker-offset
error, a sensor scale error, joint gear-ratio (scale) errors and a slow drift of the
zero-offsets over the campaign's time. The controller reports what the robot believes (the
readings); the true joint angles are

    q_true = (1 + s_j) q_reading + dtheta_j + rate_j * t + c_j * tau_gravity_j(q)

and a sensor at pose T_NR measures (1 + scale) T_NR p_marker(q_true) + noise in its own frame.
The ground truth goes to a separate file that the pipeline never reads.

The true chain's geometry (`true_chain`) is written here, apart from the fit's link-geometry
model (`remaster.inference`, `kinematics.perturbed_chain`), so that a simulated campaign tests
that model against a world it did not make: a DH robot's table with errors, rebuilt; then an
arbitrary small rigid motion of every fixed transform, applied on the side of the frame it starts
from.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .. import spatial
from ..robot.gravity import gravity_torques
from ..robot.kinematics import ForwardKinematics, KinematicChain, chain_from_dh


@dataclass(frozen=True, eq=False)
class DHErrors:
    """A DH robot's true table: the nominal rows (N, 4) [a (m), alpha (rad), d (m), theta (rad)]
    plus `errors` (N, 4) in the same units, in `convention` ('standard' or 'modified'), with the
    nominal fixed flange transform (4, 4) after the last joint. A theta error is a zero-offset
    in all but name: it adds to the joint's angle."""

    nominal_rows: np.ndarray
    errors: np.ndarray
    convention: str = "standard"
    flange: np.ndarray = field(default_factory=lambda: np.eye(4))

    @property
    def true_rows(self) -> np.ndarray:
        return np.asarray(self.nominal_rows, dtype=float) + np.asarray(self.errors, dtype=float)


@dataclass(frozen=True)
class TrueRobot:
    """What the robot really is. Angles in rad, lengths in m, compliance in rad/(N m), drift in
    rad/s; arrays of shape (N,) unless stated; None means the effect is absent.

    link_motions (N + 1, 6): for F_1..F_N, F_tool a translation t (m, 3) then roll, pitch, yaw
    r (rad, 3), F'_j = Trans(t) Rz(yaw) Ry(pitch) Rx(roll) F_j (`moved_transforms`).
    dh_errors: a DH robot's true table (`DHErrors`), applied first."""

    zero_offsets: np.ndarray
    joint_compliance: np.ndarray | None = None
    payload_mass: float = 0.0
    payload_com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    joint_scale: np.ndarray | None = None
    drift_rate: np.ndarray | None = None
    # (N, 3), or (T, N, 3) for T summed terms: amplitude (rad), cycles per turn, phase (rad) of a gear's error
    cyclic_error: np.ndarray | None = None
    link_motions: np.ndarray | None = None
    dh_errors: DHErrors | None = None
    # (N,) rad: half the play of each joint's gear, by the direction of approach (`approach`)
    backlash: np.ndarray | None = None
    # every fixed transform's translation grown by this factor (thermal growth of the links), 1
    link_scale: float = 0.0


@dataclass(frozen=True)
class Sensor:
    """A 3D sensor in the room: its pose in the robot frame (robot <- sensor, 4x4), per-axis
    noise (m), scale error (dimensionless), the nominal marker (3,) in the flange frame and the
    error of that marker's true position (3,). transverse_growth_per_m: 0 for isotropic noise;
    otherwise `noise` is a tracker's range std and its transverse std is noise sqrt(1 + (g d)^2)
    at distance d from the sensor (`remaster.noise`). orientation_noise (rad): a full-pose probe's
    std of each component of its measured rotation (0: the sensor measures a point only);
    probe_rotation (3, 3): the probe frame's nominal rotation in the flange frame, and
    probe_rotation_error (3,) rad the rotation vector of its true frame from the nominal one
    (applied in the probe's own frame)."""

    name: str
    kind: str
    pose_in_robot: np.ndarray
    noise: float
    marker: np.ndarray
    marker_error: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_error: float = 0.0
    transverse_growth_per_m: float = 0.0
    orientation_noise: float = 0.0
    probe_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    probe_rotation_error: np.ndarray = field(default_factory=lambda: np.zeros(3))

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


def moved_transforms(transforms, motions) -> np.ndarray:
    """Fixed transforms (k, 4, 4) each moved by a small rigid motion (k, 6) [t (m, 3), roll,
    pitch, yaw (rad)]: F' = Trans(t) Rz(yaw) Ry(pitch) Rx(roll) F, the motion written in the frame
    F starts from (the previous joint's), where the fit writes its errors in the frame F leads
    to, and as angles rather than a rotation vector: the same kind of error, made by other code."""
    motions = np.asarray(motions, dtype=float)
    moves = spatial.homogeneous(spatial.rpy_to_matrix(motions[:, 3], motions[:, 4], motions[:, 5]), motions[:, :3])
    return moves @ np.asarray(transforms, dtype=float)


def dh_chain(dh: DHErrors, nominal: KinematicChain) -> KinematicChain:
    """The chain of a DH table with errors, with the nominal chain's names and limits (the
    controller's), and its mass data only when its joint frames are the DH table's own."""
    rebuilt = chain_from_dh(dh.true_rows, dh.convention, dh.flange, name=nominal.name)
    if rebuilt.n_joints != nominal.n_joints:
        raise ValueError(f"the DH table has {rebuilt.n_joints} rows, the chain {nominal.n_joints} joints")
    return replace(
        nominal,
        joint_transforms=rebuilt.joint_transforms,
        joint_axes=rebuilt.joint_axes,
        tool_transform=rebuilt.tool_transform,
        inertias=nominal.inertias if same_frames_as_dh(nominal, dh) else None,
        urdf_xml=None,
    )


def same_frames_as_dh(chain: KinematicChain, dh: DHErrors, tolerance: float = 1e-9) -> bool:
    """Whether the chain's joint frames are those of the nominal DH table (then mass data given in
    them stay valid on the true table)."""
    nominal = chain_from_dh(dh.nominal_rows, dh.convention, dh.flange)
    return nominal.n_joints == chain.n_joints and bool(
        np.allclose(nominal.joint_transforms, chain.joint_transforms, rtol=0.0, atol=tolerance)
        and np.allclose(nominal.joint_axes, chain.joint_axes, rtol=0.0, atol=tolerance)
    )


def true_chain(chain: KinematicChain, robot: TrueRobot) -> KinematicChain:
    """The robot's true geometry: the nominal chain, or the DH table with its errors, then the
    rigid link motions; the nominal chain itself when it has none."""
    if robot.dh_errors is None and robot.link_motions is None and not robot.link_scale:
        return chain
    base = dh_chain(robot.dh_errors, chain) if robot.dh_errors is not None else chain
    transforms = np.concatenate([base.joint_transforms, base.tool_transform[None]])
    if robot.link_motions is not None:
        if np.shape(robot.link_motions)[0] != len(transforms):
            raise ValueError(
                f"link motions need one row per fixed transform ({len(transforms)}), got {np.shape(robot.link_motions)}"
            )
        transforms = moved_transforms(transforms, robot.link_motions)
    if robot.link_scale:
        transforms = transforms.copy()
        transforms[:, :3, 3] *= 1.0 + robot.link_scale
    return replace(base, joint_transforms=transforms[:-1], tool_transform=transforms[-1])


def approach(q_readings) -> np.ndarray:
    """(n, N) +1 or -1: the direction each joint reached each reading from, in the readings' order
    (+1: from below; the first reading, and a joint that did not move, keep the last direction, +1 at first)."""
    q = np.asarray(q_readings, dtype=float)
    step = np.sign(np.diff(q, axis=0, prepend=q[:1]))
    out = np.ones_like(q)
    for i in range(1, len(q)):
        out[i] = np.where(step[i] == 0.0, out[i - 1], step[i])
    return out


def true_joint_angles(chain: KinematicChain, robot: TrueRobot, q_readings, elapsed_s=None) -> np.ndarray:
    """True joint angles (n, N) for controller readings (n, N) at times `elapsed_s` (n,) s."""
    q = np.asarray(q_readings, dtype=float)
    true = q * (1.0 + robot.joint_scale) if robot.joint_scale is not None else q.copy()
    true = true + robot.zero_offsets
    if robot.backlash is not None:
        true = true + robot.backlash * approach(q)
    if robot.cyclic_error is not None:
        # a transmission's kinematic error, periodic in the joint's own reading (what joint_harmonics models)
        for term in np.reshape(robot.cyclic_error, (-1,) + np.shape(robot.cyclic_error)[-2:]):  # summed terms
            amplitude, cycles, phase = term.T
            true = true + amplitude * np.sin(cycles * q + phase)
    if robot.drift_rate is not None:
        if elapsed_s is None:
            raise ValueError("a drifting robot needs the time of each reading")
        true = true + np.asarray(elapsed_s, dtype=float)[:, None] * robot.drift_rate
    if robot.joint_compliance is not None:
        tau = gravity_torques(true_chain(chain, robot), true, robot.payload_mass, robot.payload_com)
        true = true + robot.joint_compliance * tau
    return true


def true_marker_positions(
    chain: KinematicChain, robot: TrueRobot, sensor: Sensor, q_readings, elapsed_s=None
) -> np.ndarray:
    """Where the sensor's marker really is, in the robot frame (n, 3)."""
    q_true = true_joint_angles(chain, robot, q_readings, elapsed_s)
    return ForwardKinematics(true_chain(chain, robot), q_true).points(sensor.marker + sensor.marker_error)


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


def measure_orientations(
    chain: KinematicChain, robot: TrueRobot, sensor: Sensor, q_readings, rng: np.random.Generator, elapsed_s=None
) -> np.ndarray:
    """A full-pose probe's readings of its own frame's rotation in the sensor frame, as rotation
    vectors (n, 3) rad: the true rotation (the true chain at the true angles, the probe's true
    mounting) turned by a noise rotation exp([e]) with e ~ N(0, orientation_noise^2 I), sensor frame.
    A sensor scale error leaves rotations alone."""
    q_true = true_joint_angles(chain, robot, q_readings, elapsed_s)
    flange = ForwardKinematics(true_chain(chain, robot), q_true).flange_poses()[:, :3, :3]
    probe = sensor.probe_rotation @ spatial.rotation_vector_to_matrix(sensor.probe_rotation_error)
    true = sensor.robot_to_sensor[:3, :3] @ flange @ probe
    noise = spatial.rotation_vector_to_matrix(rng.normal(0.0, sensor.orientation_noise, (len(true), 3)))
    return spatial.matrix_to_rotation_vector(noise @ true)


def true_sensor_positions(
    chain: KinematicChain, robot: TrueRobot, sensor: Sensor, q_readings, elapsed_s=None
) -> np.ndarray:
    """Where the sensor's marker really is, in the sensor's frame as a noiseless sensor reads it (n, 3)."""
    p_robot = true_marker_positions(chain, robot, sensor, q_readings, elapsed_s)
    return (1.0 + sensor.scale_error) * spatial.transform_points(sensor.robot_to_sensor, p_robot)


# --------------------------------------------------------------------------- sensor-side phenomena
# What happens to the sensor, not to the robot: written apart from the fit's parametrization (no
# block of the fit is a move between the sets or a distorted frame), so a campaign that has them
# tests whether the acceptance check notices what the model cannot represent.


def sensor_move(translation_m, rotation_rad) -> np.ndarray:
    """M (4, 4): a rigid move of the sensor's readings, m' = R m + t in its own frame, with
    R = Rz(rz) Ry(ry) Rx(rx) of rotation_rad (3,) [rx, ry, rz] and t = translation_m (3,)."""
    rx, ry, rz = np.asarray(rotation_rad, dtype=float)
    return spatial.homogeneous(spatial.rpy_to_matrix(rx, ry, rz), np.asarray(translation_m, dtype=float))


def frame_distortion(scales, shear) -> np.ndarray:
    """I + D (3, 3): an anisotropic linear distortion of the sensor's frame about its origin; D's
    diagonal the per-axis scale errors scales (3,) [sx, sy, sz] (1), its upper triangle the shears
    shear (3,) [xy, xz, yz] (1): x' = (1 + sx) x + xy y + xz z, y' = (1 + sy) y + yz z, z' = (1 + sz) z."""
    sx, sy, sz = np.asarray(scales, dtype=float)
    xy, xz, yz = np.asarray(shear, dtype=float)
    return np.eye(3) + np.array([[sx, xy, xz], [0.0, sy, yz], [0.0, 0.0, sz]])


def sensor_side(readings, moved_rows, move=None, distortion=None) -> np.ndarray:
    """Sensor readings (n, 3) m (noise included) as a sensor that moved and reads through a
    distorted frame gives them: the rows where moved_rows (n,) is true moved by `move` (4, 4,
    `sensor_move`; the sensor bumped between the sets), then every row mapped by `distortion`
    (3, 3, `frame_distortion`) about the sensor's origin. Either None: absent."""
    out = np.array(readings, dtype=float)
    if move is not None:
        rows = np.asarray(moved_rows, dtype=bool)
        out[rows] = spatial.transform_points(move, out[rows])
    if distortion is not None:
        out = out @ np.asarray(distortion, dtype=float).T
    return out
