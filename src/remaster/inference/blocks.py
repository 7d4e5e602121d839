"""The measurement model as parameter blocks: the paper's zero-offsets and registration, plus
optional blocks for the effects the paper's model leaves out (docs/methods.md, "Parameter blocks").

    angles_i = q_i + dtheta + c tau_i + c' tau_payload,i + s_q q_i + r t_i
               + sum_k (a_k cos k q_i + b_k sin k q_i)                               (joint space)
    p_N,i    = (I + D)(1 + s_N) T*(Theta1) T_NR FK_links(angles_i) (marker + delta)  (sensor frame)

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

Joint-space blocks are linear in their parameters: each parameter k adds theta_k * v_k,i to one
joint's angle, with v_k (n,) fixed per dataset (ones, gravity torques, readings, elapsed time).
Gravity torques come once per dataset from Pinocchio (`remaster.robot.gravity`), with a tool-plate
payload m0 that is a setting. A true payload m differs from it by a torque of a different shape
than the arm's own, which c alone cannot follow (1.5 kg off leaves several um on a laser
tracker); c' on the payload's part of the torque absorbs it exactly: c'_j = c_j (m / m0 - 1).
Link geometry is complete: each fixed transform F_j of the chain (and the tool's) gets a small rigid
motion of its own frame, six parameters (`kinematics.perturbed_transforms`), the local form of the
product-of-exponentials model (Okamura & Park 1996; Chen, Yang & Lin 2001). It is continuous (no
singularity at parallel axes, unlike DH; no Hayati parameter needed) and complete (any error of a
fixed transform is one). It is made minimal by the identification Jacobian itself
(`structural_redundancy`): at configurations spread over the joint limits, a parameter whose column
lies in the span of the zero-offsets, the registration and the parameters kept before it (the
marker offset, whether the model estimates it or not, and a sensor scale) is absorbed by them at
every configuration; it is not a parameter of the error model and is held at 0 (all six of F_1
against the registration, the tool's against the marker, each rotation about a joint's own axis
against its zero-offset, a translation along two parallel axes once). What is left is a parameter
of the robot; what this campaign's data cannot determine (a joint it never moved) keeps its prior.

A `BlockModel` shows the samplers, the Laplace fit and the metrics only names, a parameter
vector, a predict function and the paper's log-posterior. The paper's model is a `BlockModel`
without extension blocks (`paper_model`). Which extension parameters the data determine is decided in one
place, `identifiable_extension`: QR with column pivoting of the extension's Jacobian columns
after projecting out the base parameters' columns.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from .. import _kernels, spatial
from ..campaigns.campaign import SensorData
from ..errors import format_rows
from ..noise import RangeTransverse
from ..robot.gravity import Payload, assumed_payload, loaded_torques, without_mass
from ..robot.kinematics import LINK_MOTION, KernelForm, KinematicChain, perturbed_transforms
from ..robot.priors import Priors
from ..units import DEG, MM, SECONDS_PER_HOUR
from .identifiability import JACOBIAN_STEP
from .model import REGISTRATION, correction_transforms, display_scale, display_unit, parameter_names

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
# the paper's sum of squares is expanded in the zero-offsets (`BlockModel._expansion`) from this many
# rows per term of the expansion (3^N): below, summing over the rows is as fast (7 joints: about 40 us
# each way at 500 rows); above, the expansion's cost stays and the rows' grows (benchmarks/bench_expansion.py:
# 37 us against 11 us at 1,000 rows, 4.0 ms against 15 us at 100,000)
EXPANDED_ROWS_PER_TERM = 0.25
MICRORAD_PER_NM = 1e-6
# the gravity regressor's columns per body (`gravity.gravity_regressor`): its mass at the joint frame's
# origin, its first moments along the frame's axes
GRAVITY_COLUMNS = ("m", "mx", "my", "mz")
# An extension column of the Jacobian below this fraction of the longest of its own block is
# invisible in the data: e.g. the compliance of joint 1 about the vertical (zero torque), the
# scale of a joint that never moves. Within a block, so that the choice of units does not matter.
INVISIBLE = 1e-6
# An extension column whose part outside the span of the base and of the extension columns
# already kept is below this fraction of its length (the sine of its angle to that span) is
# absorbed EXACTLY by them (the first link's length by the registration's z, the marker's
# tangential offset by the last zero-offset): held at 0, as the paper's joint 1 is. Any larger
# sine is kept: its Gaussian prior, not a threshold, decides how far the data may move it.
ABSORBED = 1e-6
# Configurations over the joint limits at which structural redundancy is decided
# (`structural_redundancy`): a Halton sequence, the same every run, enough to move every joint
# through many combinations of the others for chains of up to a dozen joints.
STRUCTURAL_CONFIGURATIONS = 96
# The blocks that take part in deciding structural redundancy (`structural_redundancy`): only
# link-geometry parameters are dropped for structure; the marker offset and a sensor scale are
# quantities of the set-up, part of the span they are tested against.
GEOMETRIC = ("marker_offset", "sensor_scale", "link_geometry", "sensor_distortion")
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
# Below this sine a kept parameter is weakly determined (its std alone would grow more than a
# thousandfold): reported, so that a reader knows its prior is doing the work.
COLLINEAR = 1e-3


@dataclass(frozen=True)
class ModelSettings:
    """Settings of the extension blocks. payload_mass (kg) at payload_com (m, flange frame): the
    tool plate for the gravity torques (an error in the mass is absorbed by the compliance
    block's payload terms) when the chain's URDF carries none; a URDF that carries the tool (a
    link with mass below the last joint's own link) gives it instead, and the configured payload
    is not added on top (`payload`, `robot.gravity` for the rule); drift_column: the table column
    the drift is a rate of (None: `time` if the table has one, else the first column whose name
    contains 'temperature')."""

    payload_mass: float = 1.0
    payload_com: tuple[float, float, float] = (0.0, 0.0, 0.02)
    drift_column: str | None = None
    harmonic_orders: int = 2

    def payload(self, chain: KinematicChain) -> Payload:
        """The payload the gravity torques of `readings` assume on `chain` (`Payload.report()`
        says which and why): the URDF's tool when it carries one, else this payload."""
        return assumed_payload(chain, self.payload_mass, self.payload_com)


@dataclass(frozen=True, eq=False)
class Readings:
    """What one set of one sensor gives the model, computed once.

    rows (n,): 0-based table rows (measured ones only); q (n, N) rad; measured (n, 3) m, sensor
    frame; torques (n, N) N m: torque gravity exerts on each joint (payload included) at the
    readings; payload_torques (n, N) N m: the payload's part of it (both None when not computed:
    only the `joint_compliance` block needs them); drift (n,) s since the
    table's first time (or K since the first temperature), None without such a column;
    drift_unit 's' or 'K'; harmonic_orders: K of the `joint_harmonics` block (orders 1..K);
    weights (n, 3): the instrument's per-point std of each axis over its
    RMS over the sensor's measured rows (`point_weights`), None when the table gives none: the
    likelihood's noise of row i, axis a is then sigma weights[i, a], sigma still in metres;
    drift_gaps: why drift is None although the table has a time or temperature column
    (`drift_gaps`: the rows without a value), so that the loop closure can say so;
    orientations (n, 3, 3): a full-pose probe's measured rotation in the sensor frame, NaN rows
    where it was not measured, None for points alone; probe_rotation (3, 3): the probe frame's
    nominal rotation in the flange frame; orientation_weight (m/rad): what an orientation residual
    (rad) is multiplied by to be noise of the same sigma as a coordinate's (the stated noises' ratio,
    `orientation_fields`, then the fit's own, `fit.balanced_orientation`).
    """

    rows: np.ndarray
    q: np.ndarray
    measured: np.ndarray
    torques: np.ndarray | None = None
    payload_torques: np.ndarray | None = None
    drift: np.ndarray | None = None
    drift_unit: str | None = None
    harmonic_orders: int = 2
    weights: np.ndarray | None = None
    drift_gaps: str | None = None
    orientations: np.ndarray | None = None
    probe_rotation: np.ndarray | None = None
    orientation_weight: float = 1.0
    body_torques: np.ndarray | None = None

    def regressor(self, key: str) -> np.ndarray:
        """(n, N) values a joint-space parameter multiplies: 'ones', 'q', 'torques',
        'payload_torques', 'drift' (the same for every joint), 'cos<k>' / 'sin<k>' (of k q) or
        'body<k>.<column>' (a column of an arm without mass data's gravity regressor)."""
        if key.startswith("body"):
            body, column = key[4:].split(".")
            return self.body_torques[:, :, int(body) - 1, GRAVITY_COLUMNS.index(column)]
        if key[:3] in ("cos", "sin") and key[3:].isdigit():
            return (np.cos if key[:3] == "cos" else np.sin)(int(key[3:]) * self.q)
        if key == "ones":
            return np.ones_like(self.q)
        if key == "drift":
            return np.broadcast_to(self.drift[:, None], self.q.shape)
        return getattr(self, key)

    def subset(self, keep) -> Readings:
        """The readings of the rows keep selects ((n,) bool or indices), everything per row with them."""

        def part(values):
            return None if values is None else values[keep]

        return replace(
            self,
            rows=self.rows[keep],
            q=self.q[keep],
            measured=self.measured[keep],
            torques=part(self.torques),
            payload_torques=part(self.payload_torques),
            drift=part(self.drift),
            weights=part(self.weights),
            orientations=part(self.orientations),
            body_torques=part(self.body_torques),
        )


def _drift_column(table: pd.DataFrame, column: str | None) -> str | None:
    """The column a drift is a rate of: `column`, else `time`, else the first numeric column whose
    name holds 'temperature'; None when the table has none."""
    if column is not None:
        return column
    if "time" in table.columns:
        return "time"
    return next(
        (c for c in table.columns if "temperature" in c.lower() and pd.api.types.is_numeric_dtype(table[c].dtype)),
        None,
    )


def _drift_values(series: pd.Series) -> tuple[np.ndarray, str]:
    """(values from the first measurement, unit 's' or 'K'); NaN where the series has no value."""
    if pd.api.types.is_datetime64_any_dtype(series.dtype):
        return (series - series.min()).dt.total_seconds().to_numpy(dtype=float), "s"
    values = series.to_numpy(dtype=float)
    return values - values[0], "K"


def drift_variable(table: pd.DataFrame, column: str | None = None) -> tuple[np.ndarray, str, str] | None:
    """(values (n_rows,) in s or K from the first measurement, column, unit 's' or 'K') of the
    column a drift is a rate of, or None when the table has none (or it is not finite:
    `drift_gaps` says where)."""
    column = _drift_column(table, column)
    if column is None:
        return None
    values, unit = _drift_values(table[column])
    return (values, column, unit) if np.all(np.isfinite(values)) else None


def drift_gaps(table: pd.DataFrame, column: str | None = None) -> str | None:
    """Why a table's drift column cannot carry a drift although it has one: '<column>: no value on
    table rows ...' (a missing time stamp or temperature, or the first row's temperature missing,
    which every value is taken from); None when it has none or every value is there."""
    column = _drift_column(table, column)
    if column is None:
        return None
    series = table[column]
    missing = np.flatnonzero(series.isna().to_numpy())
    if not missing.size:
        values, _ = _drift_values(series)
        if np.all(np.isfinite(values)):
            return None
        missing = np.flatnonzero(~np.isfinite(values))
    return f"{column}: no value on table {format_rows(missing)}"


def orientation_fields(sensor: SensorData, rows) -> dict:
    """{'orientations', 'probe_rotation', 'orientation_weight'} of `Readings` at table rows for a
    sensor whose table holds a full-pose probe's orientation on some of those rows, {} otherwise
    (the rows' points alone). The weight is the position noise sigma stands for over the stated
    orientation noise: the stated `noise`, or with per-point std columns their RMS
    (`point_std_scale`); the fit then balances it (`fit.balanced_orientation`)."""
    if not sensor.has_orientation:
        return {}
    orientations = sensor.orientations(rows)
    if not np.any(np.all(np.isfinite(orientations), axis=(1, 2))):
        return {}
    scale = point_std_scale(sensor)
    position = float(sensor.noise) if scale is None else scale
    return {
        "orientations": orientations,
        "probe_rotation": np.asarray(sensor.probe_rotation, dtype=float),
        "orientation_weight": position / float(sensor.orientation_noise),
    }


def readings(
    chain: KinematicChain, sensor: SensorData, set_name: str, settings: ModelSettings = ModelSettings(), exclude=()
) -> Readings:
    """The measured rows of one set but the table rows in `exclude` (flagged gross errors), their
    positions only (the loop closure's effects and residual models are of the marker's position).
    Gravity torques are taken at the readings: zero-offsets of a fraction of a degree change
    them by well under 1 %, a compliance deflection of a few microradians."""
    rows = np.setdiff1d(sensor.measured_rows(set_name), np.asarray(exclude, dtype=int))
    q = sensor.table.loc[rows, list(sensor.joint_columns)].to_numpy(dtype=float)
    measured = sensor.table.loc[rows, ["x", "y", "z"]].to_numpy(dtype=float)
    # a URDF that carries the tool gives it; the configured payload only when it does not
    loaded = loaded_torques(chain, q, settings.payload_mass, settings.payload_com)
    torques, payload = loaded.torques, loaded.payload_torques
    drift = drift_variable(sensor.table, settings.drift_column)
    return Readings(
        rows,
        q,
        measured,
        torques,
        payload,
        None if drift is None else drift[0][rows],
        None if drift is None else drift[2],
        harmonic_orders=settings.harmonic_orders,
        weights=point_weights(sensor, rows),
        drift_gaps=None if drift is not None else drift_gaps(sensor.table, settings.drift_column),
        body_torques=loaded.body_torques,
    )


def point_weights(sensor: SensorData, rows) -> np.ndarray | None:
    """(len(rows), 3) the per-point std columns (`SensorData.point_std`) at table rows over their
    RMS over every measured row of the sensor (both sets, so that sigma means the same in each),
    None without such columns: relative weights, the fit's sigma scales them."""
    std = sensor.point_std(rows)
    return None if std is None else std / point_std_scale(sensor)


def point_std_scale(sensor: SensorData) -> float | None:
    """The RMS (m) of the per-point std columns over every measured row of the sensor: the position
    noise sigma stands for when they are given (`point_weights`); None without them."""
    every = sensor.point_std(sensor.measured_rows())
    return None if every is None else math.sqrt(float(np.mean(every**2)))


# --------------------------------------------------------------------------- parameters of each block


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
        return Parameters(("marker_offset.x", "marker_offset.y", "marker_offset.z"), np.full(3, MM), ("mm",) * 3)
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


# --------------------------------------------------------------------------- the model


class BlockModel:
    """Predicted marker positions (sensor frame) of one set's readings for base + extension blocks.

    chain: the nominal chain; data: `Readings`; marker (3,) m nominal, flange frame; t_nr (4, 4)
    the initial registration; blocks: extension block names (any order; the model orders them
    as EXTENSIONS); fixed: {parameter name: value} held (e.g. the zero-offset a free
    registration absorbs, the extension parameters the data cannot see); noise: the sensor's noise
    shape (`remaster.noise`), None for the paper's isotropic noise: the likelihood then sums the
    squares of whitened residuals (`weighted_residuals`), while `residuals` stay in metres.
    Parameters: `names` (P,) free ones, `scale` (P,) their display units in SI, `unit` (P,).
    Everything that does not depend on the parameters (sines and cosines of the readings, the
    chain's fixed transforms) is computed once.
    """

    def __init__(
        self,
        chain: KinematicChain,
        data: Readings,
        marker,
        t_nr,
        blocks: Sequence[str] = (),
        fixed: Mapping[str, float] | None = None,
        priors: Priors | None = None,
        noise: RangeTransverse | None = None,
    ):
        unknown = set(blocks) - set(EXTENSIONS)
        if unknown:
            raise ValueError(f"unknown extension blocks {sorted(unknown)}; use some of {EXTENSIONS}")
        if "drift" in blocks and data.drift is None:
            raise ValueError("a drift block needs a time or temperature column")
        if "joint_compliance" in blocks and (
            data.torques is None or data.payload_torques is None or (without_mass(chain) and data.body_torques is None)
        ):
            raise ValueError("a joint_compliance block needs the readings' gravity torques (`readings`)")
        self.chain, self.data = chain, data
        self.q, self.measured = data.q, data.measured
        self.marker = np.asarray(marker, dtype=float)
        self.t_nr = np.asarray(t_nr, dtype=float)
        self.blocks = BASE + tuple(b for b in EXTENSIONS if b in blocks)
        parts = [block_parameters(b, chain, data.drift_unit, data.harmonic_orders) for b in self.blocks]
        self.all_names = tuple(n for p in parts for n in p.names)
        self.all_scale = np.concatenate([p.scale for p in parts])
        self.all_unit = tuple(u for p in parts for u in p.unit)
        self.block_of = {n: b for b, p in zip(self.blocks, parts) for n in p.names}
        fixed = dict(fixed or {})
        unknown = set(fixed) - set(self.all_names)
        if unknown:
            raise ValueError(f"cannot hold parameters {sorted(unknown)} the model does not have")
        self.fixed = fixed
        self.free = np.array([n not in fixed for n in self.all_names])
        self.fixed_values = np.array([fixed.get(n, 0.0) for n in self.all_names])
        self._free_index = np.flatnonzero(self.free)
        self.names = tuple(n for n, f in zip(self.all_names, self.free) if f)
        self.scale = self.all_scale[self.free]
        self.unit = tuple(u for u, f in zip(self.all_unit, self.free) if f)
        self._setup_joint_space(parts)
        index = {n: i for i, n in enumerate(self.all_names)}
        self._marker_index = [index[n] for n in self.all_names if self.block_of[n] == "marker_offset"]
        self._scale_index = [index[n] for n in self.all_names if self.block_of[n] == "sensor_scale"]
        self._distortion_index = [index[n] for n in self.all_names if self.block_of[n] == "sensor_distortion"]
        self._links = (
            [(index[name], row, column) for row, column, name in link_labels(chain)]
            if "link_geometry" in self.blocks
            else []
        )
        self._kernel = KernelForm.of(chain)
        self.priors = priors
        # (P,) SI prior std of the free parameters: inf for the paper's (flat), finite for the extensions'
        self.prior_std = np.array(
            [
                math.inf if priors is None or self.block_of[n] in BASE else priors.std_of(n, data.drift_unit)
                for n in self.names
            ]
        )
        self._prior_precision = np.where(np.isfinite(self.prior_std), 1.0 / self.prior_std**2, 0.0)
        # the sensor's noise shape (`remaster.noise`): None is the paper's isotropic noise
        self.noise = noise
        self._whitening = None if noise is None else noise.whitening(self.measured)
        self.noise_log_det = 0.0 if noise is None else noise.log_det_term(self.measured)
        if data.weights is not None:  # per-point stds: S_i = sigma^2 V_i S_i' V_i, V_i = diag(weights_i)
            scaling = 1.0 / np.asarray(data.weights, dtype=float)
            shape = np.eye(3) if self._whitening is None else self._whitening
            self._whitening = scaling[:, :, None] * np.broadcast_to(shape, (len(scaling), 3, 3))
            self.noise_log_det += float(np.sum(np.log(scaling)))
        self._has_prior = bool(np.any(self._prior_precision))
        self._setup_orientation(data)
        # the paper's model (no extension block, isotropic noise: `paper_model`) has its sum of squares
        # and its random walk compiled: the samplers evaluate it hundreds of thousands of times
        self.compiled_posterior = len(self.blocks) == len(BASE) and self._whitening is None and not self.has_orientation
        self._expanded = None
        if self.compiled_posterior:
            self._start = self._kernel.start(self.marker)
            self._measured_t = np.ascontiguousarray(self.measured.T)

    def _setup_joint_space(self, parts: Sequence[Parameters]) -> None:
        """values (K, n) and joints (K,) of the joint-space parameters: angle_j += theta_k values_k."""
        index = {n: i for i, n in enumerate(self.all_names)}
        rows = [(index[n], j, key) for p in parts for n, j, key in zip(p.names, p.joints, p.regressor)]
        self._joint_params = np.array([i for i, _, _ in rows], dtype=int)
        self._joint_values_t = np.array([self.data.regressor(key)[:, j] for _, j, key in rows]).T.copy()  # (n, K)
        self._joint_onehot = np.eye(self.chain.n_joints)[[j for _, j, _ in rows]]  # (K, N)
        # the compiled kernel's form (`_kernels.points_linear`): the zero-offsets as offsets, the
        # parameters whose regressor varies by reading grouped by joint, joint j's at first[j] .. first[j + 1] - 1
        constant = np.array([key == "ones" for _, _, key in rows], dtype=bool)
        joints = np.array([j for _, j, _ in rows], dtype=int)
        order = np.flatnonzero(~constant)[np.argsort(joints[~constant], kind="stable")]
        self._offset_params, self._offset_onehot = self._joint_params[constant], self._joint_onehot[constant]
        self._kernel_params = self._joint_params[order]
        self._kernel_values = np.ascontiguousarray(self._joint_values_t[:, order].T)  # (K, n)
        self._kernel_first = np.searchsorted(joints[order], np.arange(self.chain.n_joints + 1))
        self._cos_q, self._sin_q = np.ascontiguousarray(np.cos(self.q.T)), np.ascontiguousarray(np.sin(self.q.T))

    def _setup_orientation(self, data: Readings) -> None:
        """The rows whose probe orientation was measured and their rotations (`orientation_residuals`)."""
        self.has_orientation = data.orientations is not None
        if not self.has_orientation:
            self._orientation_at = np.empty(0, dtype=int)
            return
        if {"link_geometry", "sensor_distortion"} & set(self.blocks):
            raise ValueError("a probe's orientation is modelled with the joint-space blocks only")
        measured = np.asarray(data.orientations, dtype=float)
        self._orientation_at = np.flatnonzero(np.all(np.isfinite(measured), axis=(1, 2)))
        self._measured_rotations = np.ascontiguousarray(measured[self._orientation_at])
        # what follows the last joint's z-aligned frame of the kernel form: the flange, then the probe
        tool = self._kernel.bases[-1].T @ self.chain.tool_transform[:3, :3]
        self._orientation_tail = np.ascontiguousarray(tool @ np.asarray(data.probe_rotation, dtype=float))

    @property
    def n_points(self) -> int:
        """Measured positions (rows)."""
        return len(self.q)

    @property
    def n_orientations(self) -> int:
        """Measured probe orientations (rows with one; 0 for points alone)."""
        return len(self._orientation_at)

    @property
    def n_rows(self) -> int:
        """Rows of three components the likelihood sums over: positions, then orientations."""
        return self.n_points + self.n_orientations

    @property
    def row_readings(self) -> np.ndarray:
        """(n_rows,) the reading (0..n-1) each row of `weighted_residuals` belongs to: every
        position's, then each measured orientation's."""
        return np.concatenate([np.arange(self.n_points), self._orientation_at])

    def orientation_residuals(self, theta) -> np.ndarray:
        """log(R_measured R_predicted^T) as rotation vectors (n_o, 3) or (m, n_o, 3), rad, sensor
        frame, from free parameters (P,) or (m, P): R_predicted = R_registration R_flange(angles)
        R_probe at the rows whose orientation was measured."""
        every = self.full(theta)
        stack = np.atleast_2d(every)
        out = _kernels.orientation_residuals(
            self._kernel.rotations,
            self._orientation_tail,
            np.ascontiguousarray((correction_transforms(stack[:, :6]) @ self.t_nr)[:, :3, :3]),
            np.ascontiguousarray(self.angles(stack)[:, self._orientation_at]),
            self._measured_rotations,
        )
        return out if every.ndim == 2 else out[0]

    def full(self, theta) -> np.ndarray:
        """Free parameters (..., P) -> every parameter (..., P_all), held ones at their values."""
        theta = np.asarray(theta, dtype=float)
        out = np.empty(theta.shape[:-1] + self.fixed_values.shape)
        out[...] = self.fixed_values
        out[..., self._free_index] = theta
        return out

    def predict(self, theta) -> np.ndarray:
        """Predicted positions (n, 3) or (m, n, 3) from free parameters (P,) or (m, P)."""
        return self.predict_full(self.full(theta))

    def residuals(self, theta) -> np.ndarray:
        """E = p_ref - p_predicted, (n, 3) or (m, n, 3), m."""
        return self.measured - self.predict(theta)

    def jacobian(self, theta, step: float = 1e-7) -> np.ndarray:
        """d residuals / d free parameters by central differences, (3n, P) (SI units)."""
        theta = np.asarray(theta, dtype=float)
        steps = step * np.eye(len(theta))
        both = self.residuals(np.concatenate([theta + steps, theta - steps]))
        plus, minus = both[: len(theta)], both[len(theta) :]
        return ((plus - minus) / (2 * step)).reshape(len(theta), -1).T

    def vector(self, values: Mapping[str, float]) -> np.ndarray:
        """Free-parameter vector (P,) from {name: value}; parameters not given are 0."""
        return np.array([float(values.get(n, 0.0)) for n in self.names])

    def values(self, theta) -> dict[str, float]:
        """{name: value} of every parameter (held ones included) from free parameters (P,)."""
        return dict(zip(self.all_names, self.full(theta).tolist()))

    def on(self, data: Readings) -> BlockModel:
        """The same model (blocks, registration, held parameters, priors) on other readings, e.g.
        the validation set."""
        return BlockModel(
            self.chain, data, self.marker, self.t_nr, self.blocks[len(BASE) :], self.fixed, self.priors, self.noise
        )

    def with_noise(self, noise: RangeTransverse | None) -> BlockModel:
        """The same model on the same readings with another noise shape."""
        return BlockModel(
            self.chain, self.data, self.marker, self.t_nr, self.blocks[len(BASE) :], self.fixed, self.priors, noise
        )

    def whitened(self, residuals) -> np.ndarray:
        """Residuals (n, 3) or (m, n, 3) in units of the noise's range std: W_i e_i (`remaster.noise`);
        unchanged for isotropic noise."""
        if self._whitening is None:
            return np.asarray(residuals)
        return np.einsum("nij,...nj->...ni", self._whitening, residuals)

    def weighted_residuals(self, theta) -> np.ndarray:
        """Whitened residuals (n_rows, 3) or (m, n_rows, 3): what the likelihood sums the squares of;
        a full-pose probe's orientation residuals (`orientation_residuals`) times the readings'
        orientation_weight follow the n positions' rows."""
        positions = self.whitened(self.residuals(theta))
        if not self.has_orientation:
            return positions
        orientations = self.data.orientation_weight * self.orientation_residuals(theta)
        return np.concatenate([positions, orientations], axis=-2)

    def weighted_jacobian(self, theta, step: float) -> np.ndarray:
        """d whitened residuals / d free parameters, (3 n_rows, P)."""
        if self.has_orientation:
            theta = np.asarray(theta, dtype=float)
            steps = step * np.eye(len(theta))
            both = self.weighted_residuals(np.concatenate([theta + steps, theta - steps]))
            return ((both[: len(theta)] - both[len(theta) :]) / (2 * step)).reshape(len(theta), -1).T
        jacobian = self.jacobian(theta, step)
        if self._whitening is None:
            return jacobian
        return np.einsum("nij,njp->nip", self._whitening, jacobian.reshape(self.n_points, 3, -1)).reshape(
            jacobian.shape
        )

    def log_prior(self, theta) -> np.ndarray:
        """Log of the extension blocks' Gaussian priors, up to their normalisation: scalar or (m,)."""
        theta = np.asarray(theta, dtype=float)
        return -0.5 * np.sum(theta**2 * self._prior_precision, axis=-1)

    def log_posterior(self, theta, sigma):
        """The paper's: -(3n + 2) log sigma - E / (2 sigma^2) (flat prior on the registration and
        the zero-offsets, Jeffreys' on sigma), plus the extension blocks' priors (`log_prior`);
        -inf where sigma <= 0; n counts a probe's orientations with its positions (`n_rows`).
        Scalar or (m,)."""
        if np.ndim(sigma) == 0:  # one chain step: plain floats are several times cheaper
            sigma = float(sigma)
            if sigma <= 0.0:
                value = -math.inf
            else:
                value = -(3 * self.n_rows + 2) * math.log(sigma) - float(self.sum_squares(theta)) / (
                    2.0 * sigma * sigma
                )
        else:
            sigma = np.asarray(sigma, dtype=float)
            energy = self.sum_squares(theta)
            positive = sigma > 0
            safe = np.where(positive, sigma, 1.0)
            value = -(3 * self.n_rows + 2) * np.log(safe) - energy / (2.0 * safe**2)
            value = np.where(positive, value, -np.inf)
        return value + self.log_prior(theta) if self._has_prior else value

    def prior_residuals(self, theta) -> np.ndarray:
        """theta_k / std_k of the parameters with a prior (P_prior,) or (m, P_prior): least squares'
        pseudo-observations."""
        finite = np.isfinite(self.prior_std)
        return np.asarray(theta, dtype=float)[..., finite] / self.prior_std[finite]

    def angles(self, every) -> np.ndarray:
        """Joint angles (n, N) or (m, n, N) the robot had, from every parameter (..., P_all)."""
        theta = np.asarray(every, dtype=float)[..., self._joint_params]
        return self.q + self._joint_values_t @ (theta[..., :, None] * self._joint_onehot)

    def robot_points(self, every) -> np.ndarray:
        """Marker positions (n, 3) or (m, n, 3) in the ROBOT frame from every parameter (P_all,)
        or (m, P_all): what the calibrated robot is, without the sensor's set-up. A stack is
        evaluated a chunk of vectors at a time, each chunk by one compiled call."""
        every = np.asarray(every, dtype=float)
        stack = np.atleast_2d(every)
        chunk = max(1, min(self._CHUNK, self._ANGLES_PER_CALL // max(self.q.size, 1)))
        points = np.concatenate(
            [self._robot_points(stack[begin : begin + chunk]) for begin in range(0, len(stack), chunk)]
        )
        return points if every.ndim == 2 else points[0]

    # vectors per compiled call: at most _CHUNK, and at most _ANGLES_PER_CALL joint angles in all,
    # which bounds the (chunk, n, 3) points (and the transforms of a link-geometry stack) in memory
    # whatever the campaign's size; the angles themselves are taken inside the kernel
    _CHUNK = 512
    _ANGLES_PER_CALL = 2**22  # 32 MB per array

    def _robot_points(self, stack: np.ndarray) -> np.ndarray:
        """Marker positions (m, n, 3) in the robot frame for parameter vectors (m, P_all)."""
        kernel = self._kernel
        if self._links:
            errors = np.zeros((len(stack), self.chain.n_joints + 1, len(LINK_MOTION)))
            for index, row, column in self._links:
                errors[:, row, column] = stack[:, index]
            kernel = kernel.with_transforms(
                *perturbed_transforms(self.chain.joint_transforms, self.chain.tool_transform, errors)
            )
        marker = self.marker + stack[:, self._marker_index] if self._marker_index else self.marker
        rotations, shifts = kernel.rotations, kernel.shifts
        starts = np.atleast_2d(kernel.start(marker))
        return _kernels.points_linear(
            rotations.reshape((-1,) + rotations.shape[-3:]),
            shifts.reshape((-1,) + shifts.shape[-2:]),
            starts,
            self._cos_q,
            self._sin_q,
            stack[:, self._offset_params] @ self._offset_onehot,
            self._kernel_values,
            self._kernel_first,
            np.ascontiguousarray(stack[:, self._kernel_params]),
        )

    def predict_full(self, every) -> np.ndarray:
        """Predicted positions (n, 3) or (m, n, 3) in the sensor frame from every parameter
        (P_all,) or (m, P_all). A stack is a loop over its m vectors (not over rows)."""
        every = np.asarray(every, dtype=float)
        stack = np.atleast_2d(every)
        points = self.robot_points(stack)
        transform = correction_transforms(stack[:, :6]) @ self.t_nr
        out = points @ np.swapaxes(transform[:, :3, :3], -1, -2) + transform[:, None, :3, 3]
        if self._scale_index:
            out = out * (1.0 + stack[:, self._scale_index])[:, :, None]
        if self._distortion_index:  # (I + D) p about the sensor's origin
            out = out + out @ np.swapaxes(distortion_matrix(stack[:, self._distortion_index]), -1, -2)
        return out if every.ndim == 2 else out[0]

    def sensor_rotation(self, theta) -> np.ndarray:
        """(3, 3) rotation of the registration at free parameters theta (P,): robot -> sensor frame."""
        every = np.atleast_2d(self.full(theta))
        return (correction_transforms(every[:, :6]) @ self.t_nr)[0, :3, :3]

    def sum_squares(self, theta) -> np.ndarray:
        """Sum of squared (whitened) residuals E(theta): scalar or (m,). The paper's model's is
        compiled (`_kernels.registered_sum_squares`, the same predictions summed in a loop)."""
        if not self.compiled_posterior:
            return np.sum(self.weighted_residuals(theta) ** 2, axis=(-2, -1))
        every = self.full(theta)
        stack = every.reshape(-1, every.shape[-1])
        expansion = self._expansion()
        if expansion[0].shape[0] > 0:
            energy = _kernels.expanded_sum_squares(expansion, stack, self.t_nr)
        else:
            energy = _kernels.registered_sum_squares(
                self._kernel.rotations,
                self._kernel.shifts,
                self._start,
                self._cos_q,
                self._sin_q,
                stack,
                self.t_nr,
                self._measured_t,
            )
        return energy if every.ndim == 2 else energy[0]

    def _expansion(self) -> tuple:
        """The paper's sum of squares expanded in the zero-offsets (`_kernels.expansion_sums`, about
        `fixed_values`), made at the first call when the campaign has at least `EXPANDED_ROWS_PER_TERM`
        rows per term (3^N terms): an evaluation then costs the same at any number of rows. Below,
        arrays without terms (each evaluation sums over the rows)."""
        if self._expanded is None:
            if self.n_rows >= EXPANDED_ROWS_PER_TERM * 3**self.chain.n_joints:
                sums = _kernels.expansion_sums(
                    self._kernel.rotations,
                    self._kernel.shifts,
                    self._start,
                    self._cos_q,
                    self._sin_q,
                    self.fixed_values,
                    self.t_nr,
                    self._measured_t,
                )
            else:
                sums = (np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(5))
            self._expanded = (*sums, np.ascontiguousarray(self.fixed_values, dtype=float))
        return self._expanded

    def metropolis_block(self, theta, log_prob: float, steps, log_u):
        """Random-walk Metropolis steps on the paper's model's `log_posterior` over (free
        parameters, sigma), compiled (`_kernels.metropolis_walk`): from theta (P + 1,) with its
        log_prob, proposals theta + steps[i] (m, P + 1) accepted when log_u[i] (m,) < the log-ratio.
        Returns (states (m, P + 1), their log-posteriors (m,), accepted count, index of the first
        NaN log-posterior or -1). Only for a model with `compiled_posterior`."""
        if not self.compiled_posterior:
            raise ValueError("only the paper's model (no extension block, isotropic noise) has a compiled walk")
        steps = np.ascontiguousarray(steps, dtype=float)
        states, log_probs = np.empty_like(steps), np.empty(len(steps))
        accepted, nan_at = _kernels.metropolis_walk(
            self._kernel.rotations,
            self._kernel.shifts,
            self._start,
            self._cos_q,
            self._sin_q,
            self.t_nr,
            self._measured_t,
            self._expansion(),
            self.fixed_values,
            self._free_index,
            np.asarray(theta, dtype=float),
            float(log_prob),
            steps,
            np.asarray(log_u, dtype=float),
            states,
            log_probs,
        )
        return states, log_probs, int(accepted), int(nan_at)


def paper_model(
    chain: KinematicChain, q, measured, marker, t_nr, fixed=None, table_rows=None, orientation: Mapping | None = None
) -> BlockModel:
    """The paper's model (eqs. point_mod_transf and posterior, `remaster.inference.model`): the
    registration and zero-offsets alone, flat priors, isotropic noise, for one sensor's measured
    points. q (n, N) rad; measured (n, 3) m in the sensor frame, all finite (unseen points are
    excluded by the caller, who counts them); marker (3,) m, flange frame; t_nr (4, 4) the initial
    registration; fixed: {parameter name: value} held; table_rows (n,): the sensor table's row of
    each point (default 0..n-1), the model's `data.rows`; orientation: a full-pose probe's
    `orientation_fields` at those rows (its orientations enter the likelihood beside the points)."""
    q = np.asarray(q, dtype=float)
    measured = np.asarray(measured, dtype=float)
    if measured.shape != (len(q), 3) or not np.all(np.isfinite(measured)):
        raise ValueError("measured must be finite with shape (n, 3) matching q")
    rows = np.arange(len(q)) if table_rows is None else np.asarray(table_rows, dtype=int)
    return BlockModel(chain, Readings(rows, q, measured, **(orientation or {})), marker, t_nr, (), fixed)


# --------------------------------------------------------------------------- identifiability of extensions


@dataclass(frozen=True)
class Reduction:
    """Which extension parameters the data can see at all. kept: free extension parameters (each
    under its prior); dropped: {name: why} the data cannot see ('invisible' with its relative size,
    or 'absorbed' exactly by the base and the parameters kept before it, with the sine of its angle
    to their span): held at 0 without priors, carried by their prior with them (`extended_model`);
    structural: the dropped link-geometry parameters absorbed at EVERY configuration (not
    parameters of the error model: always held at 0); weak: {name: sine} of kept parameters the
    data barely separate (sine below COLLINEAR: their prior decides them); condition_number of the
    whole model's free Jacobian with unit-length columns (so independent of units)."""

    kept: tuple[str, ...]
    dropped: dict[str, str]
    condition_number: float
    weak: dict[str, float] = field(default_factory=dict)
    structural: tuple[str, ...] = ()

    def report(self) -> dict:
        return {
            "kept": list(self.kept),
            "dropped": dict(self.dropped),
            "structurally_absorbed": list(self.structural),
            "weakly_determined_sine": dict(self.weak),
            "condition_number_unit_columns": self.condition_number,
            "method": "Gram-Schmidt (QR) of the extension's unit-length Jacobian columns in model order, from "
            "the span of the base columns; 'dropped' = the data cannot see it (held at 0 without a prior, "
            "left to its prior with one); 'structurally_absorbed' = link-geometry parameters the zero-offsets, "
            f"registration and the parameters before them absorb at {STRUCTURAL_CONFIGURATIONS} configurations "
            "spread over the joint limits (held at 0 always)",
            "invisible_below": INVISIBLE,
            "absorbed_below": ABSORBED,
            "weak_below": COLLINEAR,
        }


def spread_configurations(chain: KinematicChain, count: int = STRUCTURAL_CONFIGURATIONS) -> np.ndarray:
    """(count, N) configurations spread over the joint limits, [-pi, pi] for a joint without finite
    ones: an unscrambled Halton sequence (deterministic, no generator), its first point (the lower
    corner) skipped."""
    from scipy.stats import qmc

    unit = qmc.Halton(d=chain.n_joints, scramble=False).random(count + 1)[1:]
    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    return lower + unit * (upper - lower)


def _range_basis(columns: np.ndarray) -> np.ndarray:
    """Orthonormal basis (3n, r) of the span of columns (3n, k), rank-deficient ones included (a
    zero-offset the registration absorbs): singular vectors above ABSORBED x the largest."""
    if columns.shape[1] == 0:
        return np.zeros((columns.shape[0], 0))
    norms = np.linalg.norm(columns, axis=0)
    unit = columns[:, norms > 0] / norms[norms > 0]
    u, singular, _ = np.linalg.svd(unit, full_matrices=False)
    return u[:, singular > ABSORBED * singular[0]] if singular.size else u[:, :0]


def structural_redundancy(model: BlockModel) -> dict[str, str]:
    """{name: why} of the model's free link-geometry parameters that the zero-offsets (all of
    them, free), the registration, the marker offset (always: the tool's link error that only moves
    the marker is the marker's offset, in a model that has one or not) and the geometric parameters
    before them (sensor scale, earlier link parameters kept) absorb at every configuration:
    Gram-Schmidt of their unit-length Jacobian columns at `spread_configurations`, in model order;
    a column whose sine to that span is below ABSORBED is absorbed, and `why` names the parameters
    that absorb it."""
    if not any(model.block_of[n] == "link_geometry" for n in model.names):
        return {}
    q = spread_configurations(model.chain)
    zeros = np.zeros_like(q)
    probe_data = Readings(np.arange(len(q)), q, np.zeros((len(q), 3)), zeros, zeros)
    # the marker offset always takes part: where the marker sits on the tool is the marker's
    # parameter, not the tool link's, whether or not this model estimates it
    geometric = [b for b in model.blocks[len(BASE) :] if b in GEOMETRIC] + ["marker_offset"]
    probe = BlockModel(model.chain, probe_data, model.marker, model.t_nr, geometric)
    jacobian = probe.jacobian(np.zeros(len(probe.names)), JACOBIAN_STEP)
    lengths = np.linalg.norm(jacobian, axis=0)
    is_link = np.array([probe.block_of[n] == "link_geometry" for n in probe.names])
    candidates = set(n for n in model.names if model.block_of[n] == "link_geometry")
    kept = list(np.flatnonzero(~is_link))
    span = _range_basis(jacobian[:, kept])
    out = {}
    for i in np.flatnonzero(is_link):
        name = probe.names[i]
        if name not in candidates:
            continue
        unit = jacobian[:, i] / lengths[i] if lengths[i] > 0 else jacobian[:, i]
        outside = unit - span @ (span.T @ unit)
        outside = outside - span @ (span.T @ outside)  # twice: one pass loses orthogonality to rounding
        sine = float(np.linalg.norm(outside))
        if sine > ABSORBED:
            kept.append(i)
            span = np.column_stack([span, outside / sine])
            continue
        basis = jacobian[:, kept]
        weights = np.linalg.lstsq(basis, jacobian[:, i], rcond=None)[0] * np.linalg.norm(basis, axis=0)
        largest = np.argsort(-np.abs(weights))[:3]
        by = ", ".join(probe.names[kept[k]] for k in largest if abs(weights[k]) > 1e-3 * max(lengths[i], 1e-300))
        out[name] = f"absorbed at every configuration by {by or 'nothing: no effect'} (sine {sine:.1e})"
    return out


def identifiable_extension(model: BlockModel, theta=None) -> Reduction:
    """Which of the model's free extension parameters the data can see, at theta (default 0).

    From the Jacobian: a column shorter than INVISIBLE x the longest of its block is invisible.
    The others, scaled to unit length, go through Gram-Schmidt (QR) in the model's order,
    starting from the span of the base columns: a column whose sine to the span of the base and
    the columns kept before it is below ABSORBED is absorbed exactly (held at 0, like joint 1's
    zero-offset against the registration); every other one is kept, under its prior, and marked
    weak below COLLINEAR. The order is a priority: a block's main parameters come before its
    secondary ones (a compliance before its payload correction).
    """
    theta = np.zeros(len(model.names)) if theta is None else np.asarray(theta, dtype=float)
    jacobian = model.jacobian(theta, JACOBIAN_STEP)
    is_base = np.array([model.block_of[n] in BASE for n in model.names])
    ext_names = [n for n, b in zip(model.names, is_base) if not b]
    ext = jacobian[:, ~is_base]
    lengths = np.linalg.norm(ext, axis=0)
    longest = {}
    for name, length in zip(ext_names, lengths):
        longest[model.block_of[name]] = max(longest.get(model.block_of[name], 0.0), length)
    span, _ = np.linalg.qr(jacobian[:, is_base])
    kept, dropped, weak = [], {}, {}
    for i, name in enumerate(ext_names):
        relative = lengths[i] / longest[model.block_of[name]] if lengths[i] > 0 else 0.0
        if relative < INVISIBLE:
            dropped[name] = f"invisible: effect {relative:.1e} of the block's largest"
            continue
        outside = ext[:, i] / lengths[i] - span @ (span.T @ ext[:, i] / lengths[i])
        sine = float(np.linalg.norm(outside))
        if sine > ABSORBED:
            kept.append(i)
            span = np.column_stack([span, outside / sine])
            if sine < COLLINEAR:
                weak[name] = sine
        else:
            dropped[name] = f"absorbed: sine {sine:.1e} to the base and the parameters kept before it"
    keep = is_base.copy()
    keep[np.flatnonzero(~is_base)[kept]] = True
    columns = jacobian[:, keep]
    norms = np.linalg.norm(columns, axis=0)
    # a base column without any effect (a zero-offset of a joint the marker sits on, not held here)
    # makes the kept set singular; the others are scaled to unit length
    singular = np.linalg.svd(columns[:, norms > 0] / norms[norms > 0], compute_uv=False)
    condition = float(singular[0] / singular[-1]) if np.all(norms > 0) else np.inf
    return Reduction(tuple(ext_names[i] for i in kept), dropped, condition, weak)


def extended_model(
    chain: KinematicChain,
    data: Readings,
    marker,
    t_nr,
    blocks: Sequence[str],
    base_held: Mapping[str, float],
    priors: Priors | None = None,
    noise: RangeTransverse | None = None,
) -> tuple[BlockModel, Reduction]:
    """The model of base + blocks, under `priors`, with the base's held parameters held and the
    link-geometry parameters absorbed at every configuration held at 0 (`structural_redundancy`:
    they are not parameters of the robot). Under priors every other extension parameter is kept,
    those the data cannot see included: their prior carries them, so what they do away from the
    measured configurations (a joint that never moved, a tool that never turned) stays in the
    posterior. Without priors (flat), the parameters the data cannot see at all are held at 0 too.
    The reduction reports which are which."""
    structural = structural_redundancy(BlockModel(chain, data, marker, t_nr, blocks, base_held))
    held = {**dict(base_held), **{n: 0.0 for n in structural}}
    found = identifiable_extension(BlockModel(chain, data, marker, t_nr, blocks, held))
    reduction = Reduction(
        found.kept, {**structural, **found.dropped}, found.condition_number, found.weak, tuple(structural)
    )
    if priors is None:
        held = {**held, **{n: 0.0 for n in found.dropped}}
    return BlockModel(chain, data, marker, t_nr, blocks, held, priors, noise), reduction
