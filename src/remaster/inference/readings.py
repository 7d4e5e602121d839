"""What one set of one sensor gives the block models, computed once (`Readings`, `readings`): the
joint readings and measured points of its rows, the gravity torques at the readings (Pinocchio,
`remaster.robot.gravity`, with the payload of `ModelSettings`), the variable a drift is a rate of
(elapsed time or temperature), the per-point weights of an instrument that states its noise per
point, and a full-pose probe's orientations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ..campaigns.campaign import SensorData
from ..errors import format_rows
from ..robot.gravity import Payload, assumed_payload, loaded_torques
from ..robot.kinematics import KinematicChain

# the gravity regressor's columns per body (`gravity.gravity_regressor`): its mass at the joint frame's
# origin, its first moments along the frame's axes
GRAVITY_COLUMNS = ("m", "mx", "my", "mz")


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
