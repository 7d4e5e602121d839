"""The parameters each block of the measurement model owns (`block_parameters`): their names, SI
step units and display units, and for the joint-space blocks the joint and the readings' regressor
each multiplies (docs/methods.md, "Parameter blocks").

| block              | parameters (SI)                                        | display unit |
|--------------------|--------------------------------------------------------|--------------|
| `registration`     | x, y, z (m), alpha, beta, gamma (rad)                  | mm, deg      |
| `zero_offsets`     | q1..qN (rad)                                           | deg          |
| `joint_compliance` | q1..qN (rad/(N m)) times tau_j, gravity's torque;      | urad/(N m)   |
|                    | payload_q1..qN (rad/(N m)) times the payload's part;   |              |
|                    | an arm without masses: q<j>.body<k>.m, .mx, .my, .mz   |              |
|                    | times its gravity regressor's columns instead of q<j>  |              |
| `joint_scale`      | q1..qN (1), times the reading q_j                      | ppm          |
| `marker_offset`    | x, y, z (m) added to the marker, flange frame          | mm           |
| `sensor_scale`     | s (1): p_N -> (1 + s) p_N                              | ppm          |
| `link_geometry`    | F<j>.x, .y, .z (m), F<j>.rx, .ry, .rz (rad), tool.*    | mm, deg      |
| `drift`            | q1..qN (rad/s, or rad/K), times t_i (or T_i)           | deg/h, deg/K |
| `joint_harmonics`  | q<j>.cos<k>, q<j>.sin<k> (rad), times cos/sin(k q_j),  | deg          |
|                    | k = 1..K: joint j's cyclic (transmission) error f_j    |              |
| `sensor_distortion`| d1, d2, xy, xz, yz (1): p_N -> (I + D) p_N, D symmetric| ppm          |
|                    | and traceless (`distortion_matrix`)                    |              |

Also the forms some blocks' values take outside the model: the link errors and the calibrated
fixed transforms of the link-geometry block, the distortion matrix of the sensor-distortion block.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .. import spatial
from ..robot.gravity import without_mass
from ..robot.kinematics import LINK_MOTION, KinematicChain, perturbed_transforms
from ..units import DEG, MM, SECONDS_PER_HOUR
from .model import REGISTRATION, display_scale, display_unit, parameter_names
from .readings import GRAVITY_COLUMNS, Readings

BASE = ("registration", "zero_offsets")
EXTENSIONS = (
    "joint_compliance",
    "joint_scale",
    "marker_offset",
    "sensor_scale",
    "link_geometry",
    "drift",
    "joint_harmonics",
    "sensor_distortion",
)
PPM = 1e-6
MICRORAD_PER_NM = 1e-6
MARKER_OFFSET = ("marker_offset.x", "marker_offset.y", "marker_offset.z")  # flange frame
# The sensor frame distortion D (3, 3), symmetric and traceless (`distortion_matrix`): its
# antisymmetric part is a rotation, the registration's, and its trace is `sensor_scale`'s, so five
# parameters are left: two normal strains in an orthonormal basis of the traceless diagonals, so
# that their prior treats the three axes alike (each axis's normal strain has std sqrt(2/3) times
# the prior's), and the three shears D_xy = D_yx, D_xz, D_yz.
DISTORTION_PARTS = ("d1", "d2", "xy", "xz", "yz")
_DISTORTION_BASIS = np.array(
    [
        np.diag([1.0, -1.0, 0.0]) / math.sqrt(2.0),
        np.diag([1.0, 1.0, -2.0]) / math.sqrt(6.0),
        [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
        [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
        [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
    ]
)


@dataclass(frozen=True)
class Parameters:
    """names (P,), scale (P,) SI size of one display unit, unit (P,) its label; for a joint-space
    block, joints (P,) the joint each parameter moves and regressor (P,) the `Readings.regressor`
    it multiplies."""

    names: tuple[str, ...]
    scale: np.ndarray
    unit: tuple[str, ...]
    joints: tuple[int, ...] = ()
    regressor: tuple[str, ...] = ()


def link_labels(chain: KinematicChain) -> list[tuple[int, int, str]]:
    """(fixed transform 0..N (N: the tool), component 0..5 of `kinematics.LINK_MOTION`, parameter
    name) of the link-geometry block: link_geometry.F<j>.x .. .rz, link_geometry.tool.x .. .rz."""
    labels = [f"F{i + 1}" for i in range(chain.n_joints)] + ["tool"]
    return [
        (i, c, f"link_geometry.{label}.{part}") for i, label in enumerate(labels) for c, part in enumerate(LINK_MOTION)
    ]


def link_errors(chain: KinematicChain, values: Mapping[str, float]) -> np.ndarray:
    """(N + 1, 6) small motions of F_1..F_N, F_tool (m, rad) from parameter values {name: SI}
    (absent ones 0): the `kinematics.perturbed_transforms` form of the block."""
    errors = np.zeros((chain.n_joints + 1, len(LINK_MOTION)))
    for row, column, name in link_labels(chain):
        errors[row, column] = values.get(name, 0.0)
    return errors


def calibrated_transforms(chain: KinematicChain, values: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(F'_j Rot(a_j, d_j) (N, 4, 4), F'_tool (4, 4)): the chain's fixed transforms with the link
    geometry and zero-offsets of `values` {parameter: SI} (absent ones 0), so that a robot
    commanded to q is where the calibrated model says."""
    joints, tool = perturbed_transforms(chain.joint_transforms, chain.tool_transform, link_errors(chain, values))
    turns = [
        spatial.homogeneous(spatial.rot_axis(chain.joint_axes[j], values.get(f"zero_offsets.q{j + 1}", 0.0)))
        for j in range(chain.n_joints)
    ]
    return joints @ np.array(turns), tool


def distortion_matrix(coefficients) -> np.ndarray:
    """D (..., 3, 3), symmetric and traceless, from the `sensor_distortion` block's coefficients
    (..., 5) in `DISTORTION_PARTS` order (1): p_N -> (I + D) p_N about the sensor's origin."""
    return np.tensordot(np.asarray(coefficients, dtype=float), _DISTORTION_BASIS, axes=(-1, 0))


def distortion_coefficients(matrix) -> dict[str, float]:
    """{sensor_distortion.<part>: value} of the symmetric traceless part of a small linear map's
    error M (3, 3) (I + M about the sensor's origin): what the block can take of it. The rest is
    a rotation (the registration's, (M - M^T) / 2) and an isotropic scale (`sensor_scale`, tr M / 3)."""
    matrix = np.asarray(matrix, dtype=float)
    strain = 0.5 * (matrix + matrix.T) - np.trace(matrix) / 3.0 * np.eye(3)
    values = [float(np.sum(strain * b) / np.sum(b * b)) for b in _DISTORTION_BASIS]
    return {f"sensor_distortion.{p}": v for p, v in zip(DISTORTION_PARTS, values)}


def block_parameters(
    block: str, chain: KinematicChain, drift_unit: str | None = None, harmonic_orders: int = 2
) -> Parameters:
    """The parameters a block owns on this chain, in model order (`joint_harmonics`: orders
    1..harmonic_orders, the lower orders first, so that identifiability keeps them first)."""
    if block == "registration":  # the paper's parameters, named and scaled as `remaster.inference.model` does
        names = parameter_names(chain.n_joints)[: len(REGISTRATION)]
        scale = np.array([display_scale(n) for n in names])
        return Parameters(names, scale, tuple(display_unit(n) for n in names))
    if block == "marker_offset":
        return Parameters(MARKER_OFFSET, np.full(3, MM), ("mm",) * 3)
    if block == "sensor_scale":
        return Parameters(("sensor_scale.s",), np.array([PPM]), ("ppm",))
    if block == "sensor_distortion":
        names = tuple(f"sensor_distortion.{p}" for p in DISTORTION_PARTS)
        return Parameters(names, np.full(len(names), PPM), ("ppm",) * len(names))
    if block == "link_geometry":
        labels = link_labels(chain)
        return Parameters(
            tuple(name for _, _, name in labels),
            np.array([MM if c < 3 else DEG for _, c, _ in labels]),
            tuple("mm" if c < 3 else "deg" for _, c, _ in labels),
        )
    if block == "joint_harmonics":
        parts = [
            (f"{block}.q{j + 1}.{kind}{k}", j, f"{kind}{k}")
            for k in range(1, harmonic_orders + 1)
            for j in range(chain.n_joints)
            for kind in ("cos", "sin")
        ]
        return Parameters(
            tuple(p[0] for p in parts),
            np.full(len(parts), DEG),
            ("deg",) * len(parts),
            tuple(p[1] for p in parts),
            tuple(p[2] for p in parts),
        )
    rate = (DEG / SECONDS_PER_HOUR, "deg/h") if drift_unit != "K" else (DEG, "deg/K")
    joint_space = {  # block: ((name prefix, regressor), ...), scale, unit
        "zero_offsets": ((("q", "ones"),), DEG, "deg"),
        "joint_compliance": ((("q", "torques"), ("payload_q", "payload_torques")), MICRORAD_PER_NM, "urad/(N m)"),
        "joint_scale": ((("q", "q"),), PPM, "ppm"),
        "drift": ((("q", "drift"),), *rate),
    }
    if block not in joint_space:
        raise ValueError(f"unknown block {block!r}; blocks are {BASE + EXTENSIONS}")
    kinds, scale, unit = joint_space[block]
    parts = [(f"{block}.{prefix}{j + 1}", j, regressor) for prefix, regressor in kinds for j in range(chain.n_joints)]
    if block == "joint_compliance" and without_mass(chain):  # the arm's weight as its gravity regressor
        n = chain.n_joints
        bodies = [
            (f"{block}.q{j + 1}.body{k + 1}.{c}", j, f"body{k + 1}.{c}")
            for j in range(n)
            for k in range(j, n)
            for c in GRAVITY_COLUMNS
        ]
        parts = bodies + parts[n:]  # the payload's terms stay
    return Parameters(
        tuple(p[0] for p in parts),
        np.full(len(parts), scale),
        (unit,) * len(parts),
        tuple(p[1] for p in parts),
        tuple(p[2] for p in parts),
    )


def available(block: str, data: Readings) -> bool:
    """Whether the data can carry a block at all (a drift needs a time or temperature column
    that varies)."""
    return block != "drift" or (data.drift is not None and np.ptp(data.drift) > 0)


def carried_by_marker_offset(n_joints: int, held, free) -> frozenset[str]:
    """Of the held zero-offsets `held` (names), those a marker offset among the `free` parameter
    names carries at the marker: the last joint's. Its turn moves every point fixed to the flange
    by a constant change of the point's flange-frame position, at every configuration, which is
    what a marker offset is; where the offset is free, the marker's fitted place holds the turn, and
    drawing it again at the controller marks' tolerance would count it twice. A TCP elsewhere on the
    flange moves otherwise than the marker under that turn: not there."""
    last = f"zero_offsets.q{n_joints}"
    return frozenset({last}) if last in set(held) and set(MARKER_OFFSET) <= set(free) else frozenset()
