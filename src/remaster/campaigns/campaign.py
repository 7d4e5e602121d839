"""A measurement campaign as validated data: metadata, robot chain and one table per sensor.

Pure validation, no file access (`remaster.campaigns.folders` reads and writes campaign folders). The data
contract is docs/campaign-format.md. Every violation raises `InputError` (or `KinematicsError`
for the robot section) naming the file, the key or column, and the 0-based rows as stored.
"""

from __future__ import annotations

import datetime as dt
import difflib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from numbers import Real
from typing import Any

import numpy as np
import pandas as pd

from .. import spatial
from ..errors import (
    InputError,
    KinematicsError,
    listed,
    quoted,
    refuse_degrees,
    refuse_millimetres,
    require_columns,
)
from ..robot import registration
from ..robot.kinematics import DH_CONVENTIONS, MAX_LINK_LENGTH, KinematicChain
from ..robot.priors import check_encoders, check_override
from . import capacity

SETS = ("optimization", "validation")
SENSOR_KINDS = ("motion_capture", "laser_tracker", "other")

REQUIRED_KEYS = ("name", "date", "robot", "sensors")
OPTIONAL_KEYS = ("description", "tools")
ROBOT_KEYS = ("urdf", "base", "flange", "dh", "serial", "priors", "joint_encoders")
DH_KEYS = ("convention", "rows", "flange")
SENSOR_KEYS = ("kind", "marker", "noise", "mpe", "orientation_noise", "probe_rotation")

KEY_COLUMNS = ("set", "pose", "solution")
POSITION_COLUMNS = ("x", "y", "z")
TIME_COLUMN = "time"
# optional per-point instrument std (m): one isotropic `std`, or one per axis of the sensor frame
STD_COLUMN = "std"
AXIS_STD_COLUMNS = ("std_x", "std_y", "std_z")
MAX_STD = 0.01  # m: a per-point std above 10 mm is a unit mistake (millimetres stored as metres)
# optional orientation of a full-pose probe (a 6-DoF laser-tracker probe, a motion-capture rigid
# body): its frame's rotation in the sensor frame as a rotation vector (rad), NaN where not measured
ORIENTATION_COLUMNS = ("rx", "ry", "rz")
# A stated orientation noise (rad) of 0.1 rad (5.7 deg) or more is one written in degrees: a
# 6-DoF probe's is a few hundredths of a degree, a motion-capture rigid body's a few tenths.
MAX_ORIENTATION_NOISE = 0.1
# A sensor's stated noise or mpe (m) of 10 mm or more: a motion-capture system's is under 1 mm and a
# laser tracker's tens of um, so a value that large is one written in mm (or in um as mm).
MAX_NOISE = MAX_STD
# The marker's offset from the flange (m): a marker sits on the flange or on a tool that a
# measurement can follow, well within a metre; 1 m or more is the offset written in mm.
MAX_MARKER_OFFSET = 1.0
MAX_POSITION = 20.0  # m: a marker farther than this from the sensor's origin is a unit mistake
# Joint readings in degrees stored as radians: a reading beyond one turn (2 pi) or beyond the robot's
# joint limits by more than this margin cannot be a controller's reading in rad.
JOINT_MARGIN = math.radians(10.0)  # rad
MAX_JOINT_ANGLE = 2.0 * math.pi  # rad
N_REGISTRATION_PARAMETERS = 6  # x, y, z, alpha, beta, gamma of the registration correction

_JOINT_COLUMN = re.compile(r"q\d+")
SENSOR_NAME_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
_ISO_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")


def joint_columns(n_joints: int) -> tuple[str, ...]:
    """('q1', ..., 'qN')."""
    return tuple(f"q{j + 1}" for j in range(n_joints))


def minimum_optimization_points(n_joints: int) -> int:
    """Fewest measured optimization configurations a fit can use: their 3 coordinates each must
    outnumber the parameters (6 registration, N zero-offsets, the noise sigma); at least 3 for
    the registration."""
    return max(3, (N_REGISTRATION_PARAMETERS + n_joints + 1) // 3 + 1)


# --------------------------------------------------------------------------- data classes


@dataclass(frozen=True, eq=False)
class SensorData:
    """One sensor's measurements.

    name: the sensor's name (the Parquet file's stem); kind: one of SENSOR_KINDS;
    marker: (3,) nominal marker centre in the flange frame (m); noise: stated per-axis noise (m)
    or None; table: the validated table, rows in stored order (RangeIndex = row numbers),
    `time` (if any) as UTC timestamps, extra columns untouched; mpe: the instrument's stated
    maximum permissible error of a coordinate (m, a bound: rectangular in the uncertainty budget)
    or None; orientation_noise: the stated std (rad) of each component of a full-pose probe's
    measured rotation, and probe_rotation (3, 3) the probe frame's nominal rotation in the flange
    frame, both None unless the table has the orientation columns (`ORIENTATION_COLUMNS`).
    """

    name: str
    kind: str
    marker: np.ndarray
    noise: float | None
    table: pd.DataFrame = field(repr=False)
    mpe: float | None = None
    orientation_noise: float | None = None
    probe_rotation: np.ndarray | None = field(default=None, repr=False)

    @property
    def has_orientation(self) -> bool:
        """Whether the table holds a full-pose probe's orientation (`ORIENTATION_COLUMNS`)."""
        return all(c in self.table.columns for c in ORIENTATION_COLUMNS)

    def orientations(self, rows) -> np.ndarray:
        """The probe frame's measured rotation (len(rows), 3, 3) in the sensor frame at table rows
        (0-based), NaN where the orientation was not measured; ValueError without the columns."""
        if not self.has_orientation:
            raise ValueError(f"sensor {self.name!r} has no orientation columns {', '.join(ORIENTATION_COLUMNS)}")
        vectors = self.table.loc[np.asarray(rows, dtype=int), list(ORIENTATION_COLUMNS)].to_numpy(dtype=float)
        seen = np.all(np.isfinite(vectors), axis=1)
        out = np.full((len(vectors), 3, 3), np.nan)
        out[seen] = spatial.rotation_vector_to_matrix(vectors[seen])
        return out

    @property
    def joint_columns(self) -> tuple[str, ...]:
        """('q1', ..., 'qN') in joint order."""
        return joint_columns(sum(1 for c in self.table.columns if _JOINT_COLUMN.fullmatch(c)))

    @property
    def n_joints(self) -> int:
        return len(self.joint_columns)

    def set_mask(self, set_name: str | None = None) -> np.ndarray:
        """Boolean (n_rows,): rows of `set_name` ('optimization' or 'validation'); all rows for None."""
        if set_name is None:
            return np.ones(len(self.table), dtype=bool)
        if set_name not in SETS:
            raise ValueError(f"unknown set {set_name!r}; use one of {SETS}")
        return (self.table["set"] == set_name).to_numpy(dtype=bool)

    def q(self, set_name: str | None = None) -> np.ndarray:
        """Joint readings (n, N) in rad of the rows of `set_name` (all rows for None), stored order."""
        return self.table.loc[self.set_mask(set_name), list(self.joint_columns)].to_numpy(dtype=float)

    def positions(self, set_name: str | None = None) -> np.ndarray:
        """Measured marker centres (n, 3) in m, sensor frame, NaN rows where the marker was not seen."""
        return self.table.loc[self.set_mask(set_name), list(POSITION_COLUMNS)].to_numpy(dtype=float)

    def validation_copies(self) -> np.ndarray:
        """0-based rows of the validation set whose joint readings and measured position both equal
        an optimization row's, bit for bit: a copy, not a new measurement (a second reading of the
        same configuration differs at least by the sensor's noise), so it tests the fit on data it saw."""
        columns = list(self.joint_columns + POSITION_COLUMNS)
        seen = self.table.loc[self.set_mask("optimization") & self.measured_mask, columns]
        validation = self.table.loc[self.set_mask("validation") & self.measured_mask, columns]
        copied = validation.merge(seen.drop_duplicates(), on=columns, how="left", indicator=True)["_merge"] == "both"
        return validation.index.to_numpy()[copied.to_numpy()]

    @property
    def measured_mask(self) -> np.ndarray:
        """Boolean (n_rows,): rows with a finite measured position."""
        return np.all(np.isfinite(self.positions()), axis=1)

    def measured_rows(self, set_name: str | None = None) -> np.ndarray:
        """0-based table rows of a set (all rows for None) whose marker was seen."""
        return np.flatnonzero(self.set_mask(set_name) & self.measured_mask)

    @property
    def missing_rows(self) -> np.ndarray:
        """Row numbers (0-based, stored order) where the marker was not seen (x, y, z NaN)."""
        return np.flatnonzero(~self.measured_mask)

    @property
    def n_missing(self) -> int:
        return int(self.missing_rows.size)

    def fit_readings(self, excluded=()) -> np.ndarray:
        """(n, N) rad: the readings a fit used, the optimization rows whose marker was seen less the
        `excluded` rows (gross errors); every optimization row when that leaves none."""
        rows = np.setdiff1d(self.measured_rows("optimization"), np.asarray(excluded, dtype=int))
        return self.q()[rows] if len(rows) else self.q("optimization")

    def point_std(self, rows) -> np.ndarray | None:
        """The instrument's per-point std (len(rows), 3) m per axis of the sensor frame at table
        rows (0-based) from the optional `std` or `std_x, std_y, std_z` columns; None without them."""
        rows = np.asarray(rows, dtype=int)
        if STD_COLUMN in self.table.columns:
            return np.repeat(self.table[STD_COLUMN].to_numpy(dtype=float)[rows, None], 3, axis=1)
        if all(c in self.table.columns for c in AXIS_STD_COLUMNS):
            return self.table.loc[rows, list(AXIS_STD_COLUMNS)].to_numpy(dtype=float)
        return None


@dataclass(frozen=True, eq=False)
class Campaign:
    """A validated campaign, independent of the folder it was read from.

    robot: the robot section as written in campaign.yaml (paths as written);
    chain: the kinematic chain it describes; sensors: name -> SensorData, in YAML order; tools:
    the user's named tool centre points {name: (3,) m in the flange frame}, empty when none is given.
    """

    name: str
    date: dt.date
    description: str
    robot: dict[str, Any]
    chain: KinematicChain
    sensors: dict[str, SensorData]
    tools: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_joints(self) -> int:
        return self.chain.n_joints


# --------------------------------------------------------------------------- campaign.yaml


def _spelling_hint(unknown, allowed) -> str:
    """' (did you mean: sensor -> sensors?)' for unknown keys close to allowed ones, else ''."""
    guesses = [
        f"{k} -> {close[0]}" for k in unknown if (close := difflib.get_close_matches(str(k), allowed, n=1, cutoff=0.6))
    ]
    return f" (misspelt? {', '.join(guesses)})" if guesses else ""


def _check_keys(
    section: Mapping, allowed: tuple[str, ...], where: str, source: str, error: type[InputError] = InputError
) -> None:
    unknown = [k for k in section if k not in allowed]
    if unknown:
        raise error(
            f"unknown key{'s' if len(unknown) > 1 else ''}; allowed: {', '.join(allowed)}"
            f"{_spelling_hint(unknown, allowed)}",
            file=source,
            key=", ".join(f"{where}/{k}" if where else str(k) for k in unknown),
        )


def _mapping(value: Any, key: str, source: str, error: type[InputError] = InputError) -> Mapping:
    if not isinstance(value, Mapping):
        raise error(f"must be a mapping, got {type(value).__name__}", file=source, key=key)
    return value


def _is_number(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(value)


def _number_list(
    value: Any, length: int, key: str, source: str, what: str, error: type[InputError] = InputError
) -> list[float]:
    """A list of `length` finite numbers, or an error naming `key`."""
    if not isinstance(value, (list, tuple)) or len(value) != length or not all(_is_number(v) for v in value):
        raise error(f"must be {what}, got {quoted(value)}", file=source, key=key)
    return [float(v) for v in value]


def _parse_date(value: Any, source: str) -> dt.date:
    if isinstance(value, dt.datetime):  # YAML reads '2018-06-12T10:00:00' as a datetime
        raise InputError(
            f"must be an ISO date YYYY-MM-DD, got the date-time {value.isoformat()}", file=source, key="date"
        )
    if isinstance(value, dt.date):
        return value
    if isinstance(value, str) and _ISO_DATE.fullmatch(value.strip()):
        try:
            return dt.date.fromisoformat(value.strip())
        except ValueError:
            pass
    raise InputError(f"must be an ISO date YYYY-MM-DD, got {quoted(value)}", file=source, key="date")


def validate_robot(robot: Any, source: str) -> dict[str, Any]:
    """Check the `robot` section's structure (not the files it names); return a plain copy.

    Needs `urdf` (with optional `base`, `flange` link names) and/or `dh` (`convention`,
    `rows` of [a (m), alpha (rad), d (m), theta offset (rad)], optional 4x4 `flange`).
    Raises `KinematicsError` naming `robot/<key>`.
    """
    robot = _mapping(robot, "robot", source, KinematicsError)
    _check_keys(robot, ROBOT_KEYS, "robot", source, KinematicsError)
    if "urdf" not in robot and "dh" not in robot:
        raise KinematicsError("needs `urdf` or `dh` (or both)", file=source, key="robot")
    checked: dict[str, Any] = {}
    if "serial" in robot:  # optional: the physical unit, so that campaigns of one robot can be compared
        if not (isinstance(robot["serial"], str) and robot["serial"].strip()):
            raise KinematicsError(
                f"must be a non-empty string, got {quoted(robot['serial'])}", file=source, key="robot/serial"
            )
        checked["serial"] = robot["serial"]
    if "priors" in robot:  # optional: this robot's tolerances for the loop closure's extension blocks
        check_override(robot["priors"], source)
        checked["priors"] = dict(robot["priors"])
    if "joint_encoders" in robot:  # optional: where the encoders read the joints (the joint scale's prior)
        checked["joint_encoders"] = check_encoders(robot["joint_encoders"], source)
    if "urdf" in robot:
        for key in ("urdf", "base", "flange"):
            value = robot.get(key)
            if (key == "urdf" or value is not None) and not (isinstance(value, str) and value.strip()):
                raise KinematicsError(
                    f"must be a non-empty string, got {quoted(value)}", file=source, key=f"robot/{key}"
                )
            if value is not None:
                checked[key] = value
    else:
        frames = [k for k in ("base", "flange") if k in robot]
        if frames:
            raise KinematicsError(
                f"{' and '.join(frames)} name URDF links, but there is no `urdf`", file=source, key=f"robot/{frames[0]}"
            )
    if "dh" in robot:
        checked["dh"] = _validate_dh(robot["dh"], source)
    return checked


def _validate_dh(dh: Any, source: str) -> dict[str, Any]:
    """The `robot/dh` section checked (see `validate_robot`), as a plain copy."""
    dh = _mapping(dh, "robot/dh", source, KinematicsError)
    _check_keys(dh, DH_KEYS, "robot/dh", source, KinematicsError)
    convention = dh.get("convention")
    if convention not in DH_CONVENTIONS:
        raise KinematicsError(
            f"must be one of {', '.join(DH_CONVENTIONS)}, got {quoted(convention)}",
            file=source,
            key="robot/dh/convention",
        )
    rows = dh.get("rows")
    if not isinstance(rows, (list, tuple)) or not rows:
        raise KinematicsError(
            f"must be a non-empty list of [a, alpha, d, theta] rows, got {quoted(rows)}",
            file=source,
            key="robot/dh/rows",
        )
    malformed = [
        i
        for i, row in enumerate(rows)
        if not (isinstance(row, (list, tuple)) and len(row) == 4 and all(_is_number(v) for v in row))
    ]
    if malformed:
        raise KinematicsError(
            "each row must be 4 finite numbers [a (m), alpha (rad), d (m), theta (rad)]",
            file=source,
            key="robot/dh/rows",
            rows=malformed,
        )
    checked = {"convention": convention, "rows": [[float(v) for v in row] for row in rows]}
    refuse_millimetres(
        [[row[0], row[2]] for row in checked["rows"]],
        MAX_LINK_LENGTH,
        "the bound of a plausible link length (a, d)",
        file=source,
        key="robot/dh/rows",
        error=KinematicsError,
    )
    if not any(row[0] or row[2] for row in checked["rows"]):
        # every joint axis then passes through one point and the flange only turns about it: the
        # marker's positions can be collinear or fix no zero-offset, and the fit's figures found
        # none to draw (a ZeroDivisionError) instead of this table being named
        raise KinematicsError(
            "every link length (a and d of every row) is 0: the arm has no length (its reach is 0 m, every joint "
            "axis passes through one point); give the robot's lengths in metres",
            file=source,
            key="robot/dh/rows",
        )
    if dh.get("flange") is not None:
        flange = dh["flange"]
        if not isinstance(flange, (list, tuple)) or len(flange) != 4:
            raise KinematicsError(
                f"must be a 4x4 matrix (4 rows of 4 numbers), got {quoted(flange)}",
                file=source,
                key="robot/dh/flange",
            )
        checked["flange"] = [
            _number_list(row, 4, "robot/dh/flange", source, "a 4x4 matrix of numbers", KinematicsError)
            for row in flange
        ]
        refuse_millimetres(
            [row[3] for row in checked["flange"][:3]],
            MAX_LINK_LENGTH,
            "the bound of a plausible link length",
            file=source,
            key="robot/dh/flange",
            error=KinematicsError,
        )
    return checked


def validate_sensor_spec(name: Any, spec: Any, source: str) -> dict[str, Any]:
    """One sensor's entry of campaign.yaml checked: {'kind', 'marker' (3,) m, 'noise', 'mpe',
    'orientation_noise', 'probe_rotation' (3, 3) or None}; InputError naming `source` and the key."""
    where = f"sensors/{name}"
    if not isinstance(name, str) or not SENSOR_NAME_PATTERN.fullmatch(name):
        raise InputError("a sensor name must be a file stem (letters, digits, _ . -)", file=source, key=where)
    spec = _mapping(spec, where, source)
    _check_keys(spec, SENSOR_KEYS, where, source)
    kind = spec.get("kind")
    if kind not in SENSOR_KINDS:
        raise InputError(
            f"unknown kind {quoted(kind)}; use one of {', '.join(SENSOR_KINDS)}", file=source, key=f"{where}/kind"
        )
    if "marker" not in spec:
        raise InputError(
            "missing (the marker centre [x, y, z] in the flange frame, m)", file=source, key=f"{where}/marker"
        )
    marker = _number_list(spec["marker"], 3, f"{where}/marker", source, "3 finite numbers [x, y, z] (m)")
    refuse_millimetres(
        marker,
        MAX_MARKER_OFFSET,
        "the bound of a plausible marker offset from the flange",
        file=source,
        key=f"{where}/marker",
    )
    noise, mpe = (_positive_length(spec.get(key), f"{where}/{key}", source) for key in ("noise", "mpe"))
    for key, value in (("noise", noise), ("mpe", mpe)):
        if value is not None:
            refuse_millimetres(
                value, MAX_NOISE, "the bound of a plausible sensor noise or mpe", file=source, key=f"{where}/{key}"
            )
    out = {"kind": kind, "marker": np.array(marker), "noise": noise, "mpe": mpe}
    return out | _orientation_spec(spec, where, source)


def _orientation_spec(spec: Mapping, where: str, source: str) -> dict[str, Any]:
    """A full-pose probe's `orientation_noise` (rad) and `probe_rotation` (rotation vector, rad)
    as {'orientation_noise': float | None, 'probe_rotation': (3, 3) | None}."""
    noise = spec.get("orientation_noise")
    if noise is not None and (not _is_number(noise) or not 0 < noise < MAX_ORIENTATION_NOISE):
        raise InputError(
            f"must be a positive number below {MAX_ORIENTATION_NOISE:g} rad (the probe's orientation noise "
            f"in rad, not degrees), got {quoted(noise)}",
            file=source,
            key=f"{where}/orientation_noise",
        )
    rotation = spec.get("probe_rotation")
    if rotation is not None:
        vector = _number_list(
            rotation, 3, f"{where}/probe_rotation", source, "3 finite numbers: a rotation vector (rad)"
        )
        # [0, 0, 90] would otherwise be taken as 90 rad, that is modulo 2 pi: a turn of 5.4 rad
        refuse_degrees(vector, file=source, key=f"{where}/probe_rotation")
        rotation = spatial.rotation_vector_to_matrix(np.array(vector, dtype=float))
    return {"orientation_noise": None if noise is None else float(noise), "probe_rotation": rotation}


def _positive_length(value: Any, key: str, source: str) -> float | None:
    """An optional positive length (m) of campaign.yaml as a float, None when not given."""
    if value is None:
        return None
    if not _is_number(value) or value <= 0:
        raise InputError(f"must be a positive number (m), got {quoted(value)}", file=source, key=key)
    return float(value)


def check_folder_name(name: Any, source: str) -> None:
    """A campaign's `name` is the name of its folder, and writers (`remaster import`, `remaster
    simulate`) join it to the folder they write into: it must be one path component, or they would
    write outside that folder."""
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"must be a non-empty string, got {quoted(name)}", file=source, key="name")
    if name in (".", "..") or any(c in name for c in "/\\\0") or name != name.strip():
        raise InputError(
            f"must be a folder name (one path component: no '/', '\\', '..' or surrounding blanks), got {quoted(name)}",
            file=source,
            key="name",
        )


def validate_metadata(meta: Any, source: str) -> dict[str, Any]:
    """Check campaign.yaml's content (as loaded) against the contract; return a normalised copy.

    Returns {'name': str, 'date': datetime.date, 'description': str, 'robot': dict (see
    `validate_robot`), 'sensors': {name: {'kind': str, 'marker': (3,) m, 'noise': float | None,
    'mpe': float | None}}}.
    Does not look at files: the folder name, URDF file and Parquet files are checked by
    `folders.read_campaign`.
    """
    meta = _mapping(meta, "", source)
    missing = [k for k in REQUIRED_KEYS if k not in meta]
    if missing:
        unknown = [k for k in meta if k not in REQUIRED_KEYS + OPTIONAL_KEYS]
        raise InputError(
            f"missing required key{'s' if len(missing) > 1 else ''}"
            f"{_spelling_hint(unknown, REQUIRED_KEYS + OPTIONAL_KEYS)}",
            file=source,
            key=", ".join(missing),
        )
    _check_keys(meta, REQUIRED_KEYS + OPTIONAL_KEYS, "", source)
    name = meta["name"]
    check_folder_name(name, source)
    description = meta.get("description")
    if description is None:
        description = ""
    if not isinstance(description, str):
        raise InputError(f"must be text, got {quoted(description)}", file=source, key="description")
    sensors = _mapping(meta["sensors"], "sensors", source)
    if not sensors:
        raise InputError("names no sensor", file=source, key="sensors")
    return {
        "name": name,
        "date": _parse_date(meta["date"], source),
        "description": description,
        "robot": validate_robot(meta["robot"], source),
        "sensors": {sensor: validate_sensor_spec(sensor, spec, source) for sensor, spec in sensors.items()},
        "tools": validate_tools(meta.get("tools"), source),
    }


def validate_tools(tools: Any, source: str) -> dict[str, np.ndarray]:
    """campaign.yaml's optional `tools`: {name: [x, y, z]} the user's tool centre points in the
    flange frame (m), each finite and within `MAX_MARKER_OFFSET` of the flange (a tool in mm is
    refused); {} when absent."""
    if tools is None:
        return {}
    tools = _mapping(tools, "tools", source)
    out = {}
    for name, point in tools.items():
        if not isinstance(name, str) or not name.strip():
            raise InputError(f"a tool's name must be text, got {quoted(name)}", file=source, key="tools")
        xyz = _number_list(point, 3, f"tools/{name}", source, "3 finite numbers [x, y, z] (m, flange frame)")
        refuse_millimetres(
            xyz,
            MAX_MARKER_OFFSET,
            "the bound of a plausible tool offset from the flange",
            file=source,
            key=f"tools/{name}",
        )
        out[name] = np.array(xyz)
    return out


# --------------------------------------------------------------------------- <sensor>.parquet


def _is_text_column(series: pd.Series) -> bool:
    dtype = series.dtype
    if isinstance(dtype, pd.CategoricalDtype):
        return pd.api.types.is_object_dtype(dtype.categories.dtype) or pd.api.types.is_string_dtype(
            dtype.categories.dtype
        )
    return pd.api.types.is_object_dtype(dtype) or pd.api.types.is_string_dtype(dtype)


def _is_float64_column(series: pd.Series) -> bool:
    """float64 (numpy's or pandas' nullable Float64), as the contract says: float16 rounds a position
    of 2 m to a millimetre and a joint reading to 2 mrad, which made a calibration 18 times worse with
    nothing to say why; float32 keeps 6 digits, and a table stored in it was rounded by whatever wrote it."""
    return series.dtype == np.float64 or isinstance(series.dtype, pd.Float64Dtype)


def _is_integer_column(series: pd.Series) -> bool:
    return pd.api.types.is_integer_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype)


def _check_columns(df: pd.DataFrame, n_joints: int, source: str) -> None:
    """Column names: strings, unique, all required present, joint columns exactly q1..qN."""
    not_text = [quoted(c) for c in df.columns if not isinstance(c, str)]
    if not_text:
        raise InputError(f"column names must be strings, got {', '.join(not_text)}", file=source)
    duplicated = sorted(set(df.columns[df.columns.duplicated()]))
    if duplicated:
        raise InputError("duplicate column name(s)", file=source, key=", ".join(duplicated))
    joints = joint_columns(n_joints)
    required = KEY_COLUMNS + joints + POSITION_COLUMNS
    require_columns(df, required, file=source, note=f"the robot has {n_joints} joints, so q1..q{n_joints} are needed")
    extra_joints = [c for c in df.columns if _JOINT_COLUMN.fullmatch(c) and c not in joints]
    if extra_joints:
        raise InputError(
            f"joint column(s) that the robot does not have: it has {n_joints} joints, columns q1..q{n_joints}",
            file=source,
            key=", ".join(extra_joints),
        )


def _check_dtypes(df: pd.DataFrame, n_joints: int, source: str) -> None:
    """pose/solution integer, q/x/y/z float, set text, time datetime, other columns numeric or datetime."""
    known = set(KEY_COLUMNS + joint_columns(n_joints) + POSITION_COLUMNS + (TIME_COLUMN,))
    expectations = [
        (("set",), _is_text_column, "strings"),
        (("pose", "solution"), _is_integer_column, "integers (int64)"),
        (joint_columns(n_joints) + POSITION_COLUMNS, _is_float64_column, "floats (float64)"),
        ((TIME_COLUMN,), lambda s: pd.api.types.is_datetime64_any_dtype(s.dtype), "timestamps (UTC)"),
        (
            tuple(c for c in df.columns if c not in known),
            lambda s: pd.api.types.is_numeric_dtype(s.dtype) or pd.api.types.is_datetime64_any_dtype(s.dtype),
            "numeric or timestamps (extra columns are carried through)",
        ),
    ]
    for columns, accepts, wanted in expectations:
        for column in columns:
            if column in df.columns and not accepts(df[column]):
                dtype = df[column].dtype
                why = (
                    f": {dtype} keeps about {np.finfo(dtype).precision} significant digits, fewer than a measurement "
                    "needs (store float64)"
                    if pd.api.types.is_float_dtype(dtype) and isinstance(dtype, np.dtype)
                    else ""
                )
                raise InputError(f"must hold {wanted}, has dtype {dtype}{why}", file=source, key=column)
    for column in ("pose", "solution"):
        missing = np.flatnonzero(df[column].isna().to_numpy())
        if missing.size:
            raise InputError("missing values", file=source, key=column, rows=missing)
        negative = np.flatnonzero(df[column].to_numpy(dtype=np.int64) < 0)
        if negative.size:
            raise InputError("negative index", file=source, key=column, rows=negative)


def _check_joint_units(q: np.ndarray, n_joints: int, source: str, limits) -> None:
    """Joint readings in rad: none beyond one turn (+-2 pi) or beyond the robot's limits by more
    than JOINT_MARGIN; otherwise they look like degrees stored as radians."""
    columns = joint_columns(n_joints)
    margin_deg = math.degrees(JOINT_MARGIN)
    beyond_turn = np.abs(q) > MAX_JOINT_ANGLE + JOINT_MARGIN
    if beyond_turn.any():
        bad = [c for c, b in zip(columns, beyond_turn.any(axis=0)) if b]
        raise InputError(
            f"joint values beyond one turn (+-2 pi rad = +-360 deg, {margin_deg:g} deg margin), up to "
            f"{np.abs(q[beyond_turn]).max():.6g}: looks like degrees stored as radians (store radians)",
            file=source,
            key=", ".join(bad),
            rows=np.flatnonzero(beyond_turn.any(axis=1)),
        )
    if limits is None:
        return
    lower, upper = (np.broadcast_to(np.asarray(limit, dtype=float), (n_joints,)) for limit in limits)
    outside = (q < lower - JOINT_MARGIN) | (q > upper + JOINT_MARGIN)
    if outside.any():
        bad = np.flatnonzero(outside.any(axis=0))
        details = "; ".join(
            f"{columns[j]}: limits [{lower[j]:.4g}, {upper[j]:.4g}] rad, value {q[outside[:, j], j][0]:.6g}"
            for j in bad
        )
        raise InputError(
            f"joint values outside the robot's limits by more than {margin_deg:g} deg ({details}): "
            f"degrees stored as radians (store radians), or readings of another robot",
            file=source,
            key=", ".join(columns[j] for j in bad),
            rows=np.flatnonzero(outside.any(axis=1)),
        )


def _check_optimization_set(sets: np.ndarray, xyz: np.ndarray, seen: np.ndarray, n_joints: int, source: str) -> None:
    """Enough measured optimization configurations for a determined fit, not all on one line."""
    optimization = np.flatnonzero(sets == "optimization")
    measured = np.flatnonzero((sets == "optimization") & seen)
    needed = minimum_optimization_points(n_joints)
    if measured.size < needed:
        raise InputError(
            f"the optimization set has {measured.size} configuration(s) with a measured marker; the fit "
            f"needs at least {needed} (3 coordinates each must outnumber the "
            f"{N_REGISTRATION_PARAMETERS} registration parameters, {n_joints} zero-offsets and the noise)",
            file=source,
            key="set",
            rows=optimization,
        )
    try:
        registration.spread_out_triple(xyz[measured])
    except InputError:
        raise InputError(
            f"the measured marker positions of the optimization set all lie on one line (a triangle "
            f"through them is under {registration.MIN_SPREAD * 1e3:g} mm high): no sensor frame can be "
            f"registered from them",
            file=source,
            key="x, y, z",
            rows=measured,
        ) from None


def _check_rows(df: pd.DataFrame, n_joints: int, source: str, limits=None) -> None:
    """Values: known sets, unique (set, pose, solution), finite joints in rad (not degrees),
    plausible positions in m, an optimization set large enough to fit and not on one line."""
    sets = df["set"].astype(object).to_numpy()
    unknown = np.flatnonzero([not (isinstance(s, str) and s in SETS) for s in sets])
    if unknown.size:
        values = sorted({quoted(sets[i]) for i in unknown})
        raise InputError(
            f"unknown set value(s) {listed(values)}; use {' or '.join(SETS)}", file=source, key="set", rows=unknown
        )
    if not np.any(sets == "optimization"):
        raise InputError("no optimization rows: the calibration needs some", file=source, key="set")
    duplicated = np.flatnonzero(df.duplicated(list(KEY_COLUMNS), keep=False).to_numpy())
    if duplicated.size:
        raise InputError(
            "duplicate rows: each (set, pose, solution) may appear once",
            file=source,
            key="set, pose, solution",
            rows=duplicated,
        )

    q = df[list(joint_columns(n_joints))].to_numpy(dtype=float, na_value=np.nan)
    bad_q = np.flatnonzero(~np.all(np.isfinite(q), axis=1))
    if bad_q.size:
        columns = [c for c, bad in zip(joint_columns(n_joints), ~np.all(np.isfinite(q), axis=0)) if bad]
        raise InputError("non-finite joint values", file=source, key=", ".join(columns), rows=bad_q)
    _check_joint_units(q, n_joints, source, limits)

    xyz = df[list(POSITION_COLUMNS)].to_numpy(dtype=float, na_value=np.nan)
    nan = np.isnan(xyz)
    partial = np.flatnonzero(nan.any(axis=1) & ~nan.all(axis=1))
    if partial.size:
        raise InputError(
            "some but not all of x, y, z are NaN (NaN in all three marks an unseen marker)",
            file=source,
            key="x, y, z",
            rows=partial,
        )
    infinite = np.flatnonzero(np.isinf(xyz).any(axis=1))
    if infinite.size:
        raise InputError("infinite positions", file=source, key="x, y, z", rows=infinite)
    seen = ~nan.all(axis=1)
    norms = np.linalg.norm(np.where(nan, 0.0, xyz), axis=1)
    too_far = np.abs(np.where(nan, 0.0, xyz)).max(axis=1) > MAX_POSITION
    if seen.any() and np.median(norms[seen]) > MAX_POSITION:
        too_far |= seen & (norms > MAX_POSITION)
    if too_far.any():
        raise InputError(
            f"marker positions beyond {MAX_POSITION:g} m: looks like millimetres stored as metres (store metres)",
            file=source,
            key="x, y, z",
            rows=np.flatnonzero(too_far),
        )
    _check_optimization_set(sets, xyz, seen, n_joints, source)


def _check_std(df: pd.DataFrame, source: str) -> None:
    """The optional per-point std columns: `std` or all of `std_x, std_y, std_z` (not both forms),
    floats, finite, positive and at most MAX_STD m on every row whose marker was seen."""
    axes = [c for c in AXIS_STD_COLUMNS if c in df.columns]
    if STD_COLUMN in df.columns and axes:
        raise InputError(
            f"give the per-point std as one column {STD_COLUMN!r} or as {', '.join(AXIS_STD_COLUMNS)}, not both",
            file=source,
            key=", ".join([STD_COLUMN, *axes]),
        )
    if axes:
        require_columns(
            df, AXIS_STD_COLUMNS, file=source, note=f"per-axis std needs all of {', '.join(AXIS_STD_COLUMNS)}"
        )
    seen = np.all(np.isfinite(df[list(POSITION_COLUMNS)].to_numpy(dtype=float, na_value=np.nan)), axis=1)
    for column in [STD_COLUMN] if STD_COLUMN in df.columns else axes:
        if not pd.api.types.is_float_dtype(df[column].dtype):
            raise InputError(f"must hold floats (m), has dtype {df[column].dtype}", file=source, key=column)
        values = df[column].to_numpy(dtype=float, na_value=np.nan)
        bad = np.flatnonzero(seen & ~(np.isfinite(values) & (values > 0)))
        if bad.size:
            raise InputError(
                "a per-point std must be a positive finite number (m) on every row whose marker was seen",
                file=source,
                key=column,
                rows=bad,
            )
        large = np.flatnonzero(seen & (values > MAX_STD))
        if large.size:
            raise InputError(
                f"per-point std above {MAX_STD * 1e3:g} mm: looks like millimetres stored as metres (store metres)",
                file=source,
                key=column,
                rows=large,
            )


def _check_orientation(df: pd.DataFrame, source: str) -> None:
    """The optional orientation columns: all of `rx, ry, rz` or none, float64, each row's three
    finite or all three NaN (not measured), NaN where the marker was not seen, and each a rotation
    vector of at most pi rad."""
    present = [c for c in ORIENTATION_COLUMNS if c in df.columns]
    if not present:
        return
    require_columns(
        df, ORIENTATION_COLUMNS, file=source, note=f"an orientation needs all of {', '.join(ORIENTATION_COLUMNS)}"
    )
    for column in ORIENTATION_COLUMNS:
        if not _is_float64_column(df[column]):
            raise InputError(f"must hold float64 (rad), has dtype {df[column].dtype}", file=source, key=column)
    vectors = df[list(ORIENTATION_COLUMNS)].to_numpy(dtype=float, na_value=np.nan)
    nan = np.isnan(vectors)
    key = ", ".join(ORIENTATION_COLUMNS)
    partial = np.flatnonzero(nan.any(axis=1) & ~nan.all(axis=1))
    if partial.size:
        raise InputError(
            "some but not all of rx, ry, rz are NaN (NaN in all three marks an orientation not measured)",
            file=source,
            key=key,
            rows=partial,
        )
    unseen = np.all(np.isnan(df[list(POSITION_COLUMNS)].to_numpy(dtype=float, na_value=np.nan)), axis=1)
    orphan = np.flatnonzero(unseen & ~nan.all(axis=1))
    if orphan.size:
        raise InputError(
            "an orientation on a row whose marker was not seen (x, y, z NaN): a probe measures both",
            file=source,
            key=key,
            rows=orphan,
        )
    beyond = np.flatnonzero(~nan.any(axis=1) & ~(np.linalg.norm(np.where(nan, 0.0, vectors), axis=1) <= math.pi + 1e-9))
    if beyond.size:
        raise InputError(
            "a rotation vector longer than pi rad (an angle in degrees stored as radians, or not a rotation vector)",
            file=source,
            key=key,
            rows=beyond,
        )


def validate_sensor_table(
    df: pd.DataFrame, n_joints: int, sensor_name: str, source: str, *, limits=None
) -> pd.DataFrame:
    """Check one sensor's table against the contract for a robot of `n_joints` joints.

    `limits`: the robot's (lower, upper) joint limits (rad, +-inf when unknown); readings beyond
    them by more than JOINT_MARGIN are refused as degrees stored as radians. Readings beyond one
    turn are refused whatever the limits.

    Returns the table with a RangeIndex (row numbers as stored) and `time`, if present, as UTC
    timestamps (naive ones are taken as UTC); every other column is untouched. Rows whose x, y, z
    are all NaN (marker not seen) are kept. `source` names the file in messages.
    """
    if not isinstance(df, pd.DataFrame):
        raise InputError(f"sensor {sensor_name!r}: expected a table, got {type(df).__name__}", file=source)
    if len(df) == 0:
        raise InputError(f"sensor {sensor_name!r}: the table has no rows", file=source)
    _check_columns(df, n_joints, source)
    _check_dtypes(df, n_joints, source)
    table = df.reset_index(drop=True)
    _check_rows(table, n_joints, source, limits)
    _check_std(table, source)
    _check_orientation(table, source)
    if TIME_COLUMN in table.columns:
        time = table[TIME_COLUMN]
        table[TIME_COLUMN] = time.dt.tz_localize("UTC") if time.dt.tz is None else time.dt.tz_convert("UTC")
    return table


def sensor_data(
    name: str,
    spec: Mapping[str, Any],
    table: pd.DataFrame,
    n_joints: int,
    source: str,
    *,
    limits=None,
    metadata_source: str = "campaign.yaml",
) -> SensorData:
    """SensorData from a validated sensor spec (see `validate_metadata`) and its raw table;
    `limits` as in `validate_sensor_table`; `metadata_source` names the spec's file in messages."""
    data = SensorData(
        name=name,
        kind=spec["kind"],
        marker=np.asarray(spec["marker"], dtype=float),
        noise=spec["noise"],
        table=validate_sensor_table(table, n_joints, name, source, limits=limits),
        mpe=spec.get("mpe"),
        orientation_noise=spec.get("orientation_noise"),
        probe_rotation=spec.get("probe_rotation"),
    )
    _check_orientation_spec(data, source, metadata_source)
    return data


def _check_orientation_spec(data: SensorData, source: str, metadata_source: str) -> None:
    """A table with orientation columns needs the sensor's `orientation_noise` and `probe_rotation`
    in campaign.yaml, and its `noise` unless the table gives per-point std columns (the ratio of
    the position noise to the orientation noise weighs one against the other); those keys need the
    columns."""
    where = f"sensors/{data.name}"
    if data.has_orientation:
        needed = ("orientation_noise", "probe_rotation") + (("noise",) if data.point_std([]) is None else ())
        for key in needed:
            if getattr(data, key) is None:
                raise InputError(
                    f"missing: {source} has orientation columns {', '.join(ORIENTATION_COLUMNS)}, which need the "
                    "sensor's orientation_noise (rad), probe_rotation (the probe frame in the flange frame, a "
                    "rotation vector in rad) and noise (m; or the table's per-point std columns)",
                    file=metadata_source,
                    key=f"{where}/{key}",
                )
    elif data.orientation_noise is not None or data.probe_rotation is not None:
        raise InputError(
            f"orientation_noise and probe_rotation describe a full-pose probe, but {source} has no orientation "
            f"columns {', '.join(ORIENTATION_COLUMNS)}",
            file=metadata_source,
            key=where,
        )


def summarize(
    campaign: Campaign, memory_limit: float | None = None, draws: int = 2000, fit_rows: int = 0
) -> dict[str, Any]:
    """What a campaign holds: robot, and per sensor the rows, poses and configurations per set,
    and the rows whose marker was not seen (kept, listed by 0-based row); and whether its jobs fit
    in `memory_limit` bytes each (None: no limit) with `draws` posterior draws in the theoretical
    accuracy and a loop closure fitting at most `fit_rows` rows: InputError before any fit when
    they do not (`capacity.check`)."""
    memory = capacity.check(
        campaign.name, max((len(s.table) for s in campaign.sensors.values()), default=0), memory_limit, draws, fit_rows
    )
    sensors = {}
    for name, sensor in campaign.sensors.items():
        table = sensor.table
        sets = {}
        for set_name in SETS:
            rows = table[sensor.set_mask(set_name)]
            sets[set_name] = {
                "configurations": int(len(rows)),
                "poses": int(rows["pose"].nunique()),
                "measured": int(np.count_nonzero(sensor.measured_mask[sensor.set_mask(set_name)])),
            }
        extra = [c for c in table.columns if c not in KEY_COLUMNS + POSITION_COLUMNS + sensor.joint_columns]
        sensors[name] = {
            "kind": sensor.kind,
            "marker_m": sensor.marker.tolist(),
            "noise_m": sensor.noise,
            "mpe_m": sensor.mpe,
            "orientation_noise_rad": sensor.orientation_noise,
            "orientation_rows": (
                int(np.count_nonzero(np.all(np.isfinite(table[list(ORIENTATION_COLUMNS)].to_numpy(float)), axis=1)))
                if sensor.has_orientation
                else 0
            ),
            "rows": int(len(table)),
            "sets": sets,
            "missing_rows": sensor.missing_rows.tolist(),
            "n_missing": sensor.n_missing,
            "extra_columns": extra,
        }
    chain = campaign.chain
    return {
        "campaign": campaign.name,
        "date": campaign.date.isoformat(),
        "robot": {
            "name": chain.name,
            "serial": campaign.robot.get("serial"),
            "joints": list(chain.joint_names),
            "base": chain.base_frame,
            "flange": chain.flange_frame,
        },
        "sensors": sensors,
        "memory": memory,
    }
