"""`remaster import`: build a campaign folder from the exports people have.

Input: a controller log of joint positions (CSV, deg or rad) and one CSV export per sensor
(marker centre x, y, z in mm or m), matched row by row either by a key column (a point id in
both files) or by time (the controller row nearest in time, within a tolerance). An import
configuration (YAML or JSON) is campaign.yaml (docs/campaign-format.md) plus where the data
comes from:

```yaml
name: cell3-2024                    # campaign.yaml keys: name, date, description, robot, sensors
date: 2024-05-02
description: free text
robot: {urdf: data/robots/kuka_iiwa14.urdf, base: iiwa_link_0, flange: iiwa_link_ee}
controller:
  file: controller.csv              # relative to this configuration file
  joints: [A1, A2, A3, A4, A5, A6, A7]   # columns of q1..qN, in joint order
  unit: deg                         # deg | rad (required: no silent default)
  set: phase                        # optional column of optimization|validation (default: all optimization)
  pose: pose_id                     # optional column (default: each row its own pose, numbered within its set)
  solution: ik_solution             # optional column (default: 0)
  key: point_id                     # key column, needed when a sensor has match: key
  time: timestamp                   # time column, needed when a sensor has match: time
  time_format: iso                  # iso (default) | unix_s | unix_ms | a strptime pattern ("%d.%m.%Y %H:%M:%S")
  timezone: UTC                     # zone of times written without one (default UTC)
  delimiter: ","                    # default ","
  decimal: "."                      # "." (default) or ","
  carry: [temperature]              # optional numeric columns copied into every sensor table
sensors:
  laser_tracker:
    kind: laser_tracker             # kind, marker, noise, mpe: as in campaign.yaml
    marker: [-0.1, 0.0, 0.02]
    noise: 1.0e-5
    file: tracker.csv
    xyz: [X, Y, Z]                  # columns of x, y, z (default [x, y, z]); all three empty = marker not seen
    unit: mm                        # mm | m (required)
    match: key                      # key | time (required)
    key: point_id                   # this file's key column (default: the controller's key column name)
    time: t                         # this file's time column (default: the controller's time column name)
    tolerance: 0.5                  # s, match: time only (required there)
    # a full-pose probe (with orientation_noise and probe_rotation above): its orientation columns,
    # a rotation vector [RX, RY, RZ] with orientation_unit rad | deg, or a unit quaternion [QW, QX, QY, QZ]
    # orientation: [QW, QX, QY, QZ]
    time_format: iso                # and timezone, delimiter, decimal, carry: as for the controller
```

The controller log may instead be a ROS 2 bag (rosbag2, MCAP or sqlite3 storage) of sensor_msgs/msg/JointState
messages; the sensors are then matched by time (`match: time`, each sensor naming its `time` column):

```yaml
controller:
  bag: joints.mcap                  # relative to this configuration file; a rosbag2 .mcap or .db3 file
  topic: /joint_states              # its sensor_msgs/msg/JointState messages; other topics are ignored
  joints: [joint_a1, joint_a2, joint_a3, joint_a4, joint_a5, joint_a6, joint_a7]  # JointState names, in joint order
  stamp: header                     # header (default: header.stamp) | log (the bag's log time)
```

Each message on the topic is one controller row, in log-time order: the positions of the named
joints (rad, JointState's unit: no `unit` key, or `unit: rad`), whatever order the message lists
its names in (velocity and effort are not read and may be empty), and its time (UTC, to the ns).
As with a CSV log without these columns, every row is in the optimization set, its own pose
(numbered in order) and solution 0: `set`, `pose`, `solution` and `key`, and the CSV settings
(`file`, `time`, `time_format`, `timezone`, `delimiter`, `decimal`, `carry`), are refused with a
bag. Errors name the bag: not a readable bag, the topic absent (with the topics it has) or carrying
another type, a message without one of the joints (its index, 1-based on the topic, its log time
and the names it has), positions not one per name, a position not finite, an unset (zero) header
stamp, no message. In the report and in errors a bag's rows are its messages ("message 3").

The bag may be MCAP or sqlite3 (`bags.read_topics`), and may hold the sensor's measurements too: a
sensor section naming a `topic` (geometry_msgs PointStamped, PoseStamped, TransformStamped or a
tf2_msgs/TFMessage, `child_frame` choosing its transforms) instead of a CSV `file`:

```yaml
controller: {bag: joints.db3, topic: /joint_states, joints: [...],
             validation: {from: "2024-05-02T10:14:00Z", to: "2024-05-02T10:20:00Z"}}  # optional
sensors:
  laser_tracker: {kind: laser_tracker, marker: [...], noise: 1.0e-5,
                  topic: /tracker/point, tolerance: 0.01, still: 1.0e-6}  # bag: defaults to the controller's
```

The sensor's samples then drive the rows (`_paired_table`): each gets the joint state nearest its
time (its header stamp, or with `stamp: log` the bag's log time) within `tolerance` s, or, with
`still` (rad), the two around it interpolated when no joint moved more than that between them; the others are excluded and listed in the report. Rows
inside the controller's `validation` window form the validation set (for a CSV sensor matched to
the bag's joint states too); `validation: {bag: <file>}` instead imports a second bag of the same
topics as the validation set (`validation_spec`, `joined`).

Every controller row becomes one row of every sensor table (SI: rad, m), in the log's order; a
row no sensor row matched keeps x, y, z NaN (marker not seen, as the contract says). Sensor rows
that match no controller row are listed in import_report.json (file, 1-based line, key or time,
reason) inside the campaign folder, never silently dropped. The `time` column written is the
controller's time when the log has one, else the sensor's. Anything that cannot be parsed is an
InputError naming the file, the column and the 1-based line (the header is line 1).

This module works on text and tables only; `folders.import_campaign` reads the files (a bag's
messages decoded by `bags.read_topics`) and writes the campaign folder.
"""

from __future__ import annotations

import csv
import datetime as dt
import io as _stringio
import math
import zoneinfo
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from ..errors import (
    MAX_ROWS_SHOWN,
    ROTATION_TOLERANCE,
    InputError,
    format_rows,
    quoted,
    refuse_degrees,
    require_columns,
)
from ..units import DEG
from .campaign import (
    _JOINT_COLUMN,
    KEY_COLUMNS,
    MAX_POSITION,
    OPTIONAL_KEYS,
    ORIENTATION_COLUMNS,
    POSITION_COLUMNS,
    REQUIRED_KEYS,
    SENSOR_KEYS,
    SETS,
    TIME_COLUMN,
    _check_keys,
    _mapping,
    joint_columns,
    validate_metadata,
)

REPORT_FILE = "import_report.json"
ANGLE_UNITS = {"deg": DEG, "rad": 1.0}  # SI (rad) per unit
LENGTH_UNITS = {"mm": 1e-3, "m": 1.0}  # SI (m) per unit
MATCHES = ("key", "time")
TIME_FORMATS = ("iso", "unix_s", "unix_ms")  # or a strptime pattern (contains '%')
FILE_KEYS = ("file", "time_format", "timezone", "delimiter", "decimal", "carry")
CONTROLLER_KEYS = FILE_KEYS + ("joints", "unit", "set", "pose", "solution", "key", "time")
SENSOR_IMPORT_KEYS = FILE_KEYS + ("xyz", "unit", "match", "key", "time", "tolerance", "orientation", "orientation_unit")
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
QUATERNION_COLUMNS = ("qw", "qx", "qy", "qz")  # a sensor topic's export: a pose's orientation
QUATERNION_NORM = 1e-3  # a unit quaternion's norm off 1 by more than this is not one (or not w, x, y, z)
BAG_KEYS = ("bag", "topic", "joints", "stamp", "unit", "validation")
TOPIC_ONLY_KEYS = ("bag", "child_frame", "still", "stamp")  # a sensor topic's import keys a CSV export has not
BAG_SENSOR_KEYS = ("topic", "match", "tolerance") + TOPIC_ONLY_KEYS  # a sensor topic's import keys
_NOT_FOR_BAG_SENSOR = {  # a CSV export's sensor keys -> why they do not apply to a sensor topic
    "file": "give file (a CSV export) or topic (of a bag), not both",
    "xyz": "a message's position is its x, y, z",
    "unit": "a message's position is in m (ROS's unit)",
    "key": "a sensor topic is matched by time",
    "time": "a sample's time is its header stamp or the bag's log time: choose with stamp",
    "orientation": "a pose's or transform's orientation is its quaternion, read when the sensor has orientation_noise",
}
BAG_STAMPS = {"header": "header.stamp", "log": "log time"}  # stamp -> the name of a bag's time in messages
_NOT_FOR_BAG = {  # controller keys of a CSV log -> why they do not apply to a bag
    "file": "give file (a CSV log) or bag (a ROS 2 bag), not both",
    "set": "every joint state is in the optimization set",
    "pose": "every joint state is its own pose, numbered in log-time order",
    "solution": "every joint state is solution 0",
    "key": "a bag has no key column: match the sensors by time",
    "time": "a joint state's time is its header stamp or the bag's log time: choose with stamp",
}
WINDOW_KEYS = ("from", "to")  # controller/validation of a bag: the validation set's time window
EVERYTHING = (np.iinfo(np.int64).min, np.iinfo(np.int64).max)  # a window holding every time (ns)
_RESERVED = set(KEY_COLUMNS + POSITION_COLUMNS + ORIENTATION_COLUMNS + (TIME_COLUMN,))


def _lines(lines) -> str:
    """'line 4' or 'lines 3, 7, ... (25 in all)'."""
    return format_rows(lines, "line")


# --------------------------------------------------------------------------- CSV text


@dataclass(frozen=True, eq=False)
class Export:
    """One CSV export as text. cells: (n_rows, n_columns) str, header as column names, cells
    stripped; lines: (n_rows,) 1-based line of each row in the file (the header is line 1).

    A bag's joint states (`joint_state_export`) are one too: a row per message, `lines` its 1-based
    index on the topic, row_name "message", and `times` its times (UTC, ns) as decoded, the cells
    of its time column being only their text."""

    source: str
    cells: pd.DataFrame
    lines: np.ndarray
    row_name: str = "line"  # what `lines` count, as messages say it
    times: pd.DatetimeIndex | None = None
    frame_id: str | None = None  # a sensor topic's: the frame its positions are in

    def column(self, name: str, config_key: str) -> pd.Series:
        """Cells of column `name`; InputError naming the file and the column if it is missing."""
        require_columns(
            self.cells,
            [name],
            file=self.source,
            note=f"named by `{config_key}` of the import configuration",
            listed=True,
        )
        return self.cells[name]

    def fail(self, column: str, what: str, positions) -> InputError:
        """InputError naming the file, the column, the lines of `positions` (0-based rows) and their cells."""
        positions = list(positions)
        cells = ", ".join(quoted(self.cells[column].iloc[i]) for i in positions[:MAX_ROWS_SHOWN])
        where = format_rows(self.lines[positions], self.row_name)
        return InputError(f"{what} on {where}: {cells}", file=self.source, key=column)


def parse_csv(text: str, source: str, delimiter: str = ",") -> Export:
    """An Export of CSV `text` (first non-blank line = header; blank lines skipped).

    Raises InputError naming `source` for duplicate column names and rows whose number of
    fields differs from the header's (with their line)."""
    reader = csv.reader(_stringio.StringIO(text), delimiter=delimiter)
    header, rows, lines, previous = None, [], [], 0
    try:
        for record in reader:
            start, previous = previous + 1, reader.line_num
            if not record or all(not cell.strip() for cell in record):
                continue
            record = [cell.strip() for cell in record]
            if header is None:
                header = record
                duplicated = sorted({c for c in header if header.count(c) > 1})
                if duplicated:
                    raise InputError(
                        f"duplicate column name(s) in the header ({_lines([start])})",
                        file=source,
                        key=", ".join(duplicated),
                    )
                continue
            if len(record) != len(header):
                raise InputError(
                    f"{_lines([start])} has {len(record)} fields, the header has {len(header)} "
                    f"(delimiter {delimiter!r})",
                    file=source,
                )
            rows.append(record)
            lines.append(start)
    except csv.Error as exc:
        raise InputError(f"cannot read CSV on {_lines([reader.line_num])}: {exc}", file=source) from None
    if header is None:
        raise InputError("empty file (no header line)", file=source)
    if not rows:
        raise InputError("no data rows after the header", file=source)
    return Export(source, pd.DataFrame(rows, columns=header, dtype=object), np.asarray(lines, dtype=np.int64))


# --------------------------------------------------------------------------- configuration


@dataclass(frozen=True)
class FileSpec:
    """How to read one export: file (as written, relative to the configuration), CSV dialect,
    time format and zone of its time column, numeric columns to carry through."""

    file: str
    delimiter: str = ","
    decimal: str = "."
    time_format: str = "iso"
    timezone: str = "UTC"
    carry: tuple[str, ...] = ()


@dataclass(frozen=True)
class BagSpec:
    """A bag's topic. The controller's: sensor_msgs/msg/JointState messages, the time of each stamp
    "header" (its header.stamp) or "log" (the bag's log time), and `validation` the time window
    (from, to: ns since the Unix epoch, UTC, both included) of the validation set. A sensor's:
    measurements (bags.MEASUREMENTS), the time of each its header.stamp or the bag's log time as
    for the controller, `child_frame` the transforms taken
    (TransformStamped, TFMessage; all when None) and `still` (rad): a sample with no joint state
    within its tolerance gets the two around it interpolated when none of their joints differs by
    more than this (the robot was still between them)."""

    topic: str
    stamp: str = "header"
    validation: tuple[int, int] | None = None
    validation_bag: str | None = None  # controller/validation/bag: a second recording, all of it the validation set
    child_frame: str | None = None
    still: float | None = None


@dataclass(frozen=True)
class ControllerSpec:
    """The controller log: joint columns (q1..qN order), their unit, optional set/pose/solution
    columns, and the key and time columns used for matching. For a bag (`bag` set): file.file is
    the bag, joints are JointState names, unit rad and time the name of its stamp (BAG_STAMPS)."""

    file: FileSpec
    joints: tuple[str, ...]
    unit: str
    set: str | None = None
    pose: str | None = None
    solution: str | None = None
    key: str | None = None
    time: str | None = None
    bag: BagSpec | None = None


@dataclass(frozen=True)
class SensorSpec:
    """One sensor export: x, y, z columns and unit, matched by `key` column or `time` column
    (nearest controller time within `tolerance` s)."""

    name: str
    file: FileSpec
    xyz: tuple[str, str, str]
    unit: str
    match: str
    key: str | None = None
    time: str | None = None
    tolerance: float | None = None
    # a full-pose probe's orientation columns: a rotation vector (3, in orientation_unit rad or deg)
    # or a unit quaternion w, x, y, z (4)
    orientation: tuple[str, ...] | None = None
    orientation_unit: str | None = None
    # a sensor topic of a bag (file.file the bag): its samples drive the table's rows, each paired
    # with the controller bag's joint state nearest in time (`_paired_table`)
    bag: BagSpec | None = None


@dataclass(frozen=True)
class ImportSpec:
    """A checked import configuration: metadata is campaign.yaml's content (plain, dates ISO)."""

    source: str
    metadata: dict[str, Any]
    controller: ControllerSpec
    sensors: dict[str, SensorSpec]


def _text(section: Mapping, key: str, where: str, source: str, default: str | None = None) -> str | None:
    """A non-empty string at `key`, or `default` when the key is absent or null."""
    value = section.get(key)
    value = default if value is None else value
    if value is not None and not (isinstance(value, str) and value.strip()):
        raise InputError(f"must be a non-empty string, got {quoted(value)}", file=source, key=f"{where}/{key}")
    return value


def _choice(section: Mapping, key: str, choices, where: str, source: str, default: str | None = None) -> str:
    value = section.get(key, default)
    if value not in choices:
        got = "missing" if value is None else f"got {quoted(value)}"
        raise InputError(f"must be one of {', '.join(choices)} ({got})", file=source, key=f"{where}/{key}")
    return value


def _columns(
    section: Mapping, key: str, where: str, source: str, default=None, length: int | None = None, what: str = "column"
):
    value = section.get(key, default)
    if (
        not isinstance(value, (list, tuple))
        or not value
        or not all(isinstance(v, str) and v for v in value)
        or (length is not None and len(value) != length)
        or len(set(value)) != len(value)
    ):
        wanted = f"{length} distinct {what} names" if length else f"a list of distinct {what} names"
        raise InputError(f"must be {wanted}, got {quoted(value)}", file=source, key=f"{where}/{key}")
    return tuple(value)


def _file_spec(section: Mapping, where: str, source: str) -> FileSpec:
    file = _text(section, "file", where, source)
    if file is None:
        raise InputError("missing (the CSV file, relative to the configuration)", file=source, key=f"{where}/file")
    delimiter = _text(section, "delimiter", where, source, ",")
    decimal = _choice(section, "decimal", (".", ","), where, source, ".")
    if len(delimiter) != 1 or delimiter == decimal:
        raise InputError(
            f"must be one character other than the decimal mark {quoted(decimal)}, got {quoted(delimiter)}",
            file=source,
            key=f"{where}/delimiter",
        )
    time_format = _text(section, "time_format", where, source, "iso")
    if time_format not in TIME_FORMATS and "%" not in time_format:
        raise InputError(
            f"must be {', '.join(TIME_FORMATS)} or a strptime pattern such as '%Y-%m-%d %H:%M:%S', got {quoted(time_format)}",
            file=source,
            key=f"{where}/time_format",
        )
    timezone = _text(section, "timezone", where, source, "UTC")
    try:
        _zone(timezone)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise InputError(
            f"unknown time zone {quoted(timezone)} (an IANA name such as Europe/Berlin)",
            file=source,
            key=f"{where}/timezone",
        ) from None
    carry = _columns(section, "carry", where, source) if section.get("carry") is not None else ()
    clash = sorted(c for c in carry if c in _RESERVED or _JOINT_COLUMN.fullmatch(c))
    if clash:
        raise InputError(
            f"cannot carry column(s) {', '.join(clash)}: the contract uses these names",
            file=source,
            key=f"{where}/carry",
        )
    return FileSpec(file, delimiter, decimal, time_format, timezone, carry)


def _zone(name: str) -> dt.tzinfo:
    return dt.UTC if name.upper() == "UTC" else zoneinfo.ZoneInfo(name)


def _campaign_metadata(config: Mapping, sensors: Mapping, source: str) -> dict:
    """campaign.yaml's content of an import configuration: its own keys and each sensor's kind,
    marker, noise and mpe, validated (`validate_metadata`)."""
    campaign_yaml = {k: v for k, v in config.items() if k != "controller"}
    if sensors:  # campaign.yaml's part of each sensor section; validate_metadata names what is missing
        campaign_yaml["sensors"] = {n: {k: v for k, v in s.items() if k in SENSOR_KEYS} for n, s in sensors.items()}
    meta = validate_metadata(campaign_yaml, source)
    return {
        "name": meta["name"],
        "date": meta["date"].isoformat(),
        "description": meta["description"],
        "robot": meta["robot"],
        "sensors": {
            n: {
                "kind": s["kind"],
                "marker": s["marker"].tolist(),
                **{key: s[key] for key in ("noise", "mpe", "orientation_noise") if s[key] is not None},
                **({} if s["probe_rotation"] is None else {"probe_rotation": sensors[n]["probe_rotation"]}),
            }
            for n, s in meta["sensors"].items()
        },
    }


def _controller_spec(config: Mapping, source: str) -> ControllerSpec:
    """The configuration's `controller` section, checked."""
    if "controller" not in config:
        raise InputError("missing (the controller log: file, joints, unit, ...)", file=source, key="controller")
    section = _mapping(config["controller"], "controller", source)
    _check_keys(section, CONTROLLER_KEYS + ("bag", "topic", "stamp", "validation"), "controller", source)
    if section.get("bag") is not None:
        return _bag_controller_spec(section, source)
    if section.get("file") is None:
        raise InputError(
            "missing: file (a CSV log) or bag (a ROS 2 bag, .mcap or .db3), relative to the configuration",
            file=source,
            key="controller/file",
        )
    stray = [k for k in ("topic", "stamp") if k in section]
    if stray:
        raise InputError("only applies to a bag (controller/bag)", file=source, key=f"controller/{stray[0]}")
    return ControllerSpec(
        file=_file_spec(section, "controller", source),
        joints=_columns(section, "joints", "controller", source),
        unit=_choice(section, "unit", tuple(ANGLE_UNITS), "controller", source),
        **{k: _text(section, k, "controller", source) for k in ("set", "pose", "solution", "key", "time")},
    )


def _bag_controller_spec(section: Mapping, source: str) -> ControllerSpec:
    """A `controller` section naming a bag (controller/bag), checked: the keys of a CSV log are
    refused, saying why; a unit other than rad too (JointState positions are in rad)."""
    for key in section:
        if key not in BAG_KEYS:
            why = _NOT_FOR_BAG.get(key, "a setting of a CSV log")
            raise InputError(f"does not apply to a bag: {why}", file=source, key=f"controller/{key}")
    bag = _text(section, "bag", "controller", source)
    topic = _text(section, "topic", "controller", source)
    if topic is None:
        raise InputError(
            "missing (the bag's topic of sensor_msgs/msg/JointState messages, e.g. /joint_states)",
            file=source,
            key="controller/topic",
        )
    if section.get("unit", "rad") != "rad":
        raise InputError(
            f"must be rad or absent for a bag (JointState positions are in rad), got {quoted(section['unit'])}",
            file=source,
            key="controller/unit",
        )
    stamp = _choice(section, "stamp", tuple(BAG_STAMPS), "controller", source, "header")
    return ControllerSpec(
        file=FileSpec(bag),
        joints=_columns(section, "joints", "controller", source, what="joint"),
        unit="rad",
        time=BAG_STAMPS[stamp],
        bag=BagSpec(topic, stamp, *_validation(section.get("validation"), "controller/validation", source)),
    )


def _validation(section: Any, where: str, source: str) -> tuple[tuple[int, int] | None, str | None]:
    """controller/validation: a time window {from, to} (`_window`) or a second bag {bag: <file>},
    whose every sample is the validation set; (window, bag), None for what is not given."""
    if isinstance(section, Mapping) and "bag" in section:
        _check_keys(section, ("bag",), where, source)
        return None, _text(section, "bag", where, source)
    return _window(section, where, source), None


def _window(section: Any, where: str, source: str) -> tuple[int, int] | None:
    """controller/validation {from: <time>, to: <time>} as (from, to) ns UTC: ISO 8601 times (or
    YAML's own timestamps), UTC when written without a zone; None when absent."""
    if section is None:
        return None
    section = _mapping(section, where, source)
    _check_keys(section, WINDOW_KEYS + ("bag",), where, source)
    ends = []
    for key in WINDOW_KEYS:
        value = section.get(key)
        try:
            stamp = pd.Timestamp(value) if isinstance(value, str | dt.datetime) else None
        except ValueError:
            stamp = None
        if stamp is None or pd.isna(stamp):
            raise InputError(
                f"must be an ISO 8601 time such as 2024-05-02T10:00:30Z, got {quoted(value)}",
                file=source,
                key=f"{where}/{key}",
            )
        ends.append((stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")).value)
    if ends[0] > ends[1]:
        raise InputError("from is after to", file=source, key=where)
    return ends[0], ends[1]


def _sensor_match(spec: SensorSpec, controller: ControllerSpec, source: str) -> None:
    """InputError naming the configuration's key when the controller log cannot be matched as the
    sensor asks: by key without a key column (a bag has none), by time without a time column."""
    where = f"sensors/{spec.name}"
    if controller.bag is not None and spec.match == "key":
        raise InputError(
            f"sensor {spec.name!r} is matched by key, but a bag's joint states have no key: use match: time",
            file=source,
            key=f"{where}/match",
        )
    if controller.bag is not None and spec.match == "time" and spec.time is None:
        raise InputError(
            "missing: the sensor's time column (with a controller bag there is no column name to default to)",
            file=source,
            key=f"{where}/time",
        )
    if getattr(controller, spec.match) is None:
        raise InputError(
            f"missing: sensor {spec.name!r} is matched by {spec.match}, so the controller log needs a {spec.match} column",
            file=source,
            key=f"controller/{spec.match}",
        )


def _orientation_columns(section: Mapping, where: str, source: str) -> dict[str, Any]:
    """A full-pose probe's `orientation` columns: 3 (a rotation vector, with `orientation_unit` rad or
    deg) or 4 (a unit quaternion w, x, y, z, without a unit); {} without them."""
    if section.get("orientation") is None:
        if section.get("orientation_unit") is not None:
            raise InputError(
                "is an orientation's: give the orientation columns", file=source, key=f"{where}/orientation_unit"
            )
        return {}
    columns = _columns(section, "orientation", where, source)
    if len(columns) not in (3, 4):
        raise InputError(
            f"must be 3 columns (a rotation vector) or 4 (a unit quaternion w, x, y, z), got {quoted(list(columns))}",
            file=source,
            key=f"{where}/orientation",
        )
    unit = section.get("orientation_unit")
    if len(columns) == 3:
        unit = _choice(section, "orientation_unit", tuple(ANGLE_UNITS), where, source)
    elif unit is not None:
        raise InputError(
            "a quaternion has no unit: leave orientation_unit out", file=source, key=f"{where}/orientation_unit"
        )
    return {"orientation": columns, "orientation_unit": unit}


def _orientations(spec: SensorSpec, export: Export, xyz: np.ndarray) -> np.ndarray | None:
    """A full-pose probe's orientations (n_rows, 3) as rotation vectors (rad) from its export, NaN
    where all its columns are empty (and refused where the positions xyz (n_rows, 3) are); None
    without orientation columns."""
    if spec.orientation is None:
        return None
    where = f"sensors/{spec.name}/orientation"
    values = np.column_stack(
        [_numbers(export, c, where, spec.file.decimal, allow_missing=True) for c in spec.orientation]
    )
    empty = np.isnan(values)
    partial = np.flatnonzero(empty.any(axis=1) & ~empty.all(axis=1))
    if partial.size:
        raise InputError(
            f"some but not all orientation columns empty on {_lines(export.lines[partial])}",
            file=export.source,
            key=", ".join(spec.orientation),
        )
    orphan = np.flatnonzero(np.isnan(xyz).all(axis=1) & ~empty.all(axis=1))
    if orphan.size:
        raise InputError(
            f"an orientation where x, y, z are empty on {_lines(export.lines[orphan])}: a probe measures both",
            file=export.source,
            key=", ".join(spec.orientation),
        )
    seen = ~empty.any(axis=1)
    out = np.full((len(values), 3), np.nan)
    if len(spec.orientation) == 3:
        out[seen] = _rotation_vectors(values[seen], spec, export, export.lines[seen])
        return out
    norm = np.linalg.norm(values, axis=1)
    off = np.flatnonzero(seen & (np.abs(norm - 1.0) > QUATERNION_NORM))
    if off.size:
        raise InputError(
            f"not a unit quaternion (w, x, y, z) on {_lines(export.lines[off])}",
            file=export.source,
            key=", ".join(spec.orientation),
        )
    quaternion = values[seen] / norm[seen, None]
    quaternion *= np.where(quaternion[:, :1] < 0, -1.0, 1.0)  # w >= 0: the angle at most pi
    sine = np.linalg.norm(quaternion[:, 1:], axis=1)
    angle = 2.0 * np.arctan2(sine, quaternion[:, 0])
    ratio = np.where(sine > 1e-12, angle / np.where(sine > 1e-12, sine, 1.0), 2.0)
    out[seen] = ratio[:, None] * quaternion[:, 1:]
    return out


def _rotation_vectors(values: np.ndarray, spec: SensorSpec, export: Export, lines: np.ndarray) -> np.ndarray:
    """Rotation vectors (n, 3) rad of an export's values (n, 3) in spec.orientation_unit, on its
    `lines`, each of norm at most pi: in rad, a norm beyond pi (and ROTATION_TOLERANCE) is refused
    as degrees written for radians; in degrees, a norm beyond a turn is refused, and one between
    180 and 360 deg (a rotation a probe may well report) becomes the same rotation the short way,
    the vector of norm 2 pi - |v| about the opposite axis."""
    key = ", ".join(spec.orientation)
    if spec.orientation_unit == "rad":
        refuse_degrees(
            values,
            file=export.source,
            key=key,
            rows=lines,
            row_name=export.row_name,
            advice="if the export is in degrees, set orientation_unit: deg",
        )
    else:
        turn = np.flatnonzero(np.linalg.norm(values, axis=1) > 360.0 + np.degrees(ROTATION_TOLERANCE))
        if turn.size:
            raise InputError(
                f"a rotation vector longer than a turn (360 deg) with orientation_unit deg, up to "
                f"{np.linalg.norm(values[turn], axis=1).max():.6g} deg: not a rotation vector in degrees "
                f"(is the unit right?) on {format_rows(lines[turn], export.row_name)}",
                file=export.source,
                key=key,
            )
    vectors = values * ANGLE_UNITS[spec.orientation_unit]
    norm = np.linalg.norm(vectors, axis=1)
    long = norm > math.pi
    vectors[long] *= (1.0 - 2.0 * math.pi / norm[long])[:, None]
    return vectors


def _positive(section: Mapping, key: str, where: str, source: str, what: str) -> float:
    value = section.get(key)
    if not (isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and value > 0):
        raise InputError(f"must be a positive number of {what}, got {quoted(value)}", file=source, key=f"{where}/{key}")
    return float(value)


def _bag_sensor_spec(name: str, section: Mapping, controller: ControllerSpec, source: str) -> SensorSpec:
    """A `sensors/<name>` section naming a bag's topic (sensors/<name>/topic), checked: the keys of
    a CSV export are refused, saying why; the bag defaults to the controller's, which must be one."""
    where = f"sensors/{name}"
    for key in section:
        if key not in BAG_SENSOR_KEYS + SENSOR_KEYS:
            why = _NOT_FOR_BAG_SENSOR.get(key, "a setting of a CSV export")
            raise InputError(f"does not apply to a sensor topic: {why}", file=source, key=f"{where}/{key}")
    if controller.bag is None:
        raise InputError(
            "a sensor topic is paired with a bag's joint states: give the controller's bag (controller/bag)",
            file=source,
            key=f"{where}/topic",
        )
    _choice(section, "match", ("time",), where, source, "time")
    still = section.get("still")
    return SensorSpec(
        name=name,
        file=FileSpec(_text(section, "bag", where, source, controller.file.file)),
        xyz=POSITION_COLUMNS,
        unit="m",
        match="time",
        time=TIME_COLUMN,
        tolerance=_positive(section, "tolerance", where, source, "seconds"),
        orientation=QUATERNION_COLUMNS if section.get("orientation_noise") is not None else None,
        bag=BagSpec(
            _text(section, "topic", where, source),
            stamp=_choice(section, "stamp", tuple(BAG_STAMPS), where, source, "header"),
            child_frame=_text(section, "child_frame", where, source),
            still=None if still is None else _positive(section, "still", where, source, "rad"),
        ),
    )


def _sensor_spec(name: str, section: Mapping, controller: ControllerSpec, source: str) -> SensorSpec:
    """One `sensors/<name>` section's export, checked against the controller log it is matched to:
    the column it is matched by, a time match's tolerance, no column carried from both."""
    where = f"sensors/{name}"
    if section.get("topic") is not None:
        return _bag_sensor_spec(name, section, controller, source)
    if controller.bag is not None and controller.bag.validation_bag is not None:
        raise InputError(
            "a CSV export with a validation bag (controller/validation/bag): the validation bag holds the "
            "sensors' topics, so name this sensor's topic",
            file=source,
            key=f"{where}/file",
        )
    stray = [k for k in TOPIC_ONLY_KEYS if k in section]
    if stray:
        raise InputError(
            "only applies to a sensor topic (sensors/<name>/topic)", file=source, key=f"{where}/{stray[0]}"
        )
    match = _choice(section, "match", MATCHES, where, source)
    spec = SensorSpec(
        name=name,
        file=_file_spec(section, where, source),
        xyz=_columns(section, "xyz", where, source, list(POSITION_COLUMNS), 3),
        unit=_choice(section, "unit", tuple(LENGTH_UNITS), where, source),
        match=match,
        key=_text(section, "key", where, source, controller.key),
        time=_text(section, "time", where, source, controller.time if controller.bag is None else None),
        tolerance=section.get("tolerance"),
        **_orientation_columns(section, where, source),
    )
    _sensor_match(spec, controller, source)
    if match == "time":
        tolerance = spec.tolerance
        if not (
            isinstance(tolerance, (int, float))
            and not isinstance(tolerance, bool)
            and math.isfinite(tolerance)
            and tolerance > 0
        ):
            raise InputError(
                f"must be a positive number of seconds for match: time, got {quoted(tolerance)}",
                file=source,
                key=f"{where}/tolerance",
            )
    elif spec.tolerance is not None:
        raise InputError("only applies to match: time", file=source, key=f"{where}/tolerance")
    clash = sorted(set(controller.file.carry) & set(spec.file.carry))
    if clash:
        raise InputError(
            f"column(s) {', '.join(clash)} carried from the controller log too", file=source, key=f"{where}/carry"
        )
    return spec


def validation_spec(spec: ImportSpec) -> ImportSpec:
    """The import of a validation bag (controller/validation/bag): the controller's and every
    sensor's topic read from it, every sample in the validation set."""
    bag = spec.controller.bag.validation_bag
    controller = replace(
        spec.controller,
        file=FileSpec(bag),
        bag=replace(spec.controller.bag, validation=EVERYTHING, validation_bag=None),
    )
    sensors = {name: replace(s, file=FileSpec(bag)) for name, s in spec.sensors.items()}
    return replace(spec, controller=controller, sensors=sensors)


def joined(result: ImportResult, validation: ImportResult) -> ImportResult:
    """A campaign's import with its validation bag's (`validation_spec`): each sensor's table, the
    validation bag's rows after the first's; the report's `validation_bag` the second's sections."""
    tables = {n: pd.concat([t, validation.tables[n]], ignore_index=True) for n, t in result.tables.items()}
    report = {
        **result.report,
        "validation_bag": {k: validation.report[k] for k in ("controller", "sensors")},
        "unmatched_rows": result.report["unmatched_rows"] + validation.report["unmatched_rows"],
    }
    return replace(result, tables=tables, report=report, validation=validation)


def parse_config(config: Any, source: str) -> ImportSpec:
    """Check an import configuration (as loaded from YAML/JSON); errors name `source` and the key."""
    config = _mapping(config, "", source)
    _check_keys(config, REQUIRED_KEYS + OPTIONAL_KEYS + ("controller",), "", source)
    sensors = _mapping(config.get("sensors", {}), "sensors", source)
    for name, section in sensors.items():
        _check_keys(
            _mapping(section, f"sensors/{name}", source),
            SENSOR_KEYS + SENSOR_IMPORT_KEYS + ("topic",) + TOPIC_ONLY_KEYS,
            f"sensors/{name}",
            source,
        )
    metadata = _campaign_metadata(config, sensors, source)
    controller = _controller_spec(config, source)
    specs = {name: _sensor_spec(name, section, controller, source) for name, section in sensors.items()}
    return ImportSpec(source=source, metadata=metadata, controller=controller, sensors=specs)


# --------------------------------------------------------------------------- cells -> values


def _numbers(export: Export, column: str, config_key: str, decimal: str, allow_missing: bool) -> np.ndarray:
    """Floats (n_rows,) of a column; empty or 'nan' cells are NaN where allowed, else an error."""
    cells = export.column(column, config_key)
    values = np.full(len(cells), np.nan)
    bad, missing = [], []
    for i, cell in enumerate(cells):
        if cell == "" or cell.lower() == "nan":
            missing.append(i)
            continue
        try:
            values[i] = float(cell.replace(decimal, ".") if decimal != "." else cell)
        except ValueError:
            bad.append(i)
            continue
        if not math.isfinite(values[i]):
            bad.append(i)
    if bad:
        raise export.fail(column, "not a finite number", bad)
    if missing and not allow_missing:
        raise export.fail(column, "missing value", missing)
    return values


def _indices(export: Export, column: str, config_key: str) -> np.ndarray:
    """Non-negative integers (n_rows,) int64 of a column."""
    values = _numbers(export, column, config_key, ".", allow_missing=False)
    bad = np.flatnonzero((values < 0) | (values != np.round(values)))
    if bad.size:
        raise export.fail(column, "not a non-negative integer", bad)
    return values.astype(np.int64)


def _keys(export: Export, column: str, config_key: str) -> np.ndarray:
    """Key cells (n_rows,) as text: none empty, none repeated."""
    keys = export.column(column, config_key).to_numpy(dtype=object)
    empty = np.flatnonzero(keys == "")
    if empty.size:
        raise export.fail(column, "missing key", empty)
    duplicated = np.flatnonzero(pd.Series(keys).duplicated(keep=False).to_numpy())
    if duplicated.size:
        raise export.fail(column, "duplicate keys (each key may appear once)", duplicated)
    return keys


def _parse_time(cell: str, spec: FileSpec) -> pd.Timestamp:
    if spec.time_format in ("unix_s", "unix_ms"):
        number = float(cell.replace(spec.decimal, "."))
        if not math.isfinite(number):
            raise ValueError(cell)
        return pd.Timestamp(number, unit="s" if spec.time_format == "unix_s" else "ms", tz="UTC")
    moment = (
        dt.datetime.fromisoformat(cell) if spec.time_format == "iso" else dt.datetime.strptime(cell, spec.time_format)
    )
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=_zone(spec.timezone))
    return pd.Timestamp(moment).tz_convert("UTC")


def _times(export: Export, column: str, config_key: str, spec: FileSpec) -> pd.DatetimeIndex:
    """UTC timestamps (n_rows,) of a column; times without a zone are in spec.timezone."""
    cells = export.column(column, config_key)
    values, bad = [], []
    for i, cell in enumerate(cells):
        try:
            values.append(_parse_time(cell, spec))
        except (ValueError, OverflowError):
            bad.append(i)
    if bad:
        raise export.fail(column, f"not a time (time_format {spec.time_format})", bad)
    return pd.DatetimeIndex(values).as_unit("ns")


# --------------------------------------------------------------------------- a bag's joint states


def _utc(ns: int) -> str:
    """A time in ns since the Unix epoch as ISO 8601 text in UTC, to the ns."""
    return pd.Timestamp(int(ns), unit="ns", tz="UTC").isoformat()


def _joint_positions(state, joints: tuple[str, ...], topic: str, source: str) -> list[float]:
    """The positions (rad) of `joints`, in that order, in one JointState message (`bags.JointState`),
    whatever the order of its names; InputError naming the bag, the topic and the message (its
    index and log time) when one is missing or named twice, or its positions are not one per name
    or not finite."""
    where = f"message {state.index} (log time {_utc(state.log_time)})"
    if len(state.position) != len(state.name):
        raise InputError(
            f"{where} has {len(state.name)} names but {len(state.position)} positions (one per name)",
            file=source,
            key=topic,
        )
    missing = [j for j in joints if j not in state.name]
    twice = [j for j in joints if state.name.count(j) > 1]
    if missing or twice:
        what = f"no joint {', '.join(missing)}" if missing else f"joint {', '.join(twice)} more than once"
        raise InputError(f"{where} has {what}; its names: {', '.join(state.name) or 'none'}", file=source, key=topic)
    positions = [state.position[state.name.index(j)] for j in joints]
    bad = [f"{j} = {p}" for j, p in zip(joints, positions) if not math.isfinite(p)]
    if bad:
        raise InputError(f"{where}: position not finite: {', '.join(bad)}", file=source, key=topic)
    return positions


def _stamps_set(ns: np.ndarray, lines: np.ndarray, source: str, topic: str, remedy: str) -> None:
    """InputError naming the bag (`source`), the topic and the messages (`lines`) whose time ns is 0:
    a header stamp the publisher never set; `remedy` says what to do."""
    unset = np.flatnonzero(ns == 0)
    if unset.size:
        raise InputError(
            f"header stamp 0 (never set by the publisher) on {format_rows(lines[unset], 'message')}: {remedy}",
            file=source,
            key=topic,
        )


def joint_state_export(states: Sequence, spec: ControllerSpec, source: str) -> Export:
    """A bag's joint states (`bags.JointState`, in log-time order) as the controller log: a row per
    message, the cells the positions of spec.joints (rad, as text that reads back to the same float)
    and the text of its time (column spec.time), `lines` the messages' indices and `times` their
    header stamps or log times (spec.bag.stamp; UTC, to the ns). InputError naming the bag
    (`source`) and the topic for a message without one of the joints, positions not one per name or
    not finite, or a header stamp never set (0)."""
    bag = spec.bag
    q = [_joint_positions(state, spec.joints, bag.topic, source) for state in states]
    lines = np.array([state.index for state in states], dtype=np.int64)
    ns = np.array([state.stamp if bag.stamp == "header" else state.log_time for state in states], dtype=np.int64)
    _stamps_set(ns, lines, source, bag.topic, "use stamp: log to take the bag's log time")
    times = pd.DatetimeIndex(pd.to_datetime(ns, unit="ns", utc=True)).as_unit("ns")
    cells = {joint: [repr(float(row[j])) for row in q] for j, joint in enumerate(spec.joints)}
    cells[spec.time] = [_utc(t) for t in ns]
    return Export(source, pd.DataFrame(cells, dtype=object), lines, row_name="message", times=times)


def measurement_export(samples: Sequence, spec: SensorSpec, source: str) -> Export:
    """A sensor topic's samples (`bags.Measurement`, in log-time order) as the sensor's export: a row
    per sample, the cells x, y, z (m) and, for a full-pose probe (spec.orientation), its quaternion,
    and the text of its time (its header stamp or the bag's log time: spec.bag.stamp; UTC, to the
    ns); `lines` the messages' indices, `times` those times, `frame_id` theirs. InputError naming
    the bag (`source`) and the topic: no sample (no
    transform to spec.bag.child_frame), a header stamp 0, positions in more than one frame, a
    point where the probe needs an orientation."""
    topic = spec.bag.topic
    if not samples:
        raise InputError(
            f"no transform to child frame {spec.bag.child_frame!r} in its messages (sensors/{spec.name}/child_frame)",
            file=source,
            key=topic,
        )
    lines = np.array([m.index for m in samples], dtype=np.int64)
    header = spec.bag.stamp == "header"
    ns = np.array([m.stamp if header else m.log_time for m in samples], dtype=np.int64)
    _stamps_set(ns, lines, source, topic, f"use sensors/{spec.name}/stamp: log to take the bag's log time")
    frames: dict[str, list[int]] = {}
    for m in samples:
        frames.setdefault(m.frame_id, []).append(m.index)
    if len(frames) > 1:  # one table's positions are in one frame: the registration fits one transform
        each = "; ".join(f"{f!r} on {format_rows(ix, 'message')}" for f, ix in frames.items())
        raise InputError(f"positions in more than one frame: {each}", file=source, key=topic)
    cells = {c: [repr(m.xyz[i]) for m in samples] for i, c in enumerate(POSITION_COLUMNS)}
    if spec.orientation is not None:
        points = [m.index for m in samples if m.quaternion is None]
        if points:
            raise InputError(
                f"points without an orientation on {format_rows(points, 'message')}: a full-pose probe "
                f"(sensors/{spec.name}/orientation_noise) needs PoseStamped, TransformStamped or TFMessage",
                file=source,
                key=topic,
            )
        cells |= {c: [repr(m.quaternion[i]) for m in samples] for i, c in enumerate(QUATERNION_COLUMNS)}
    cells[TIME_COLUMN] = [_utc(t) for t in ns]
    times = pd.DatetimeIndex(pd.to_datetime(ns, unit="ns", utc=True)).as_unit("ns")
    return Export(
        source, pd.DataFrame(cells, dtype=object), lines, row_name="message", times=times, frame_id=next(iter(frames))
    )


def _window_sets(times: pd.DatetimeIndex, window: tuple[int, int] | None) -> np.ndarray:
    """The set of each time: validation inside `window` (ns UTC, ends included), else optimization."""
    inside = np.zeros(len(times), bool) if window is None else (times.asi8 >= window[0]) & (times.asi8 <= window[1])
    return np.where(inside, SETS[1], SETS[0]).astype(object)


# --------------------------------------------------------------------------- matching


def _pair(
    joint_ns: np.ndarray, q: np.ndarray, sample_ns: np.ndarray, tolerance: float, still: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str | None]]:
    """Each sensor sample's joint state: the nearest in time (earlier one on a tie) within
    `tolerance` s, else, with `still` (rad), the two around it interpolated linearly to its time
    when no joint differs between them by more than `still` (the robot stood still: what it held
    then is known however far apart the states are). Returns the joint-state row of each sample
    (the nearest; -1: unpaired), q at each sample (n, N) rad, whether it was interpolated, and why
    each unpaired one is."""
    order = np.argsort(joint_ns, kind="stable")
    t, qs = joint_ns[order], q[order]
    right = np.clip(np.searchsorted(t, sample_ns), 0, len(t) - 1)
    left = np.clip(right - 1, 0, len(t) - 1)
    nearest = np.where(np.abs(sample_ns - t[left]) <= np.abs(t[right] - sample_ns), left, right)
    gap = np.abs(sample_ns - t[nearest]) / 1e9  # s
    close = gap <= tolerance
    between = (left < right) & (t[left] <= sample_ns) & (sample_ns <= t[right])
    moved = np.abs(qs[right] - qs[left]).max(axis=1)  # rad
    interpolated = ~close & between & (still is not None) & (moved <= (still or 0.0))
    weight = (sample_ns - t[left]) / np.maximum(t[right] - t[left], 1)
    q_at = np.where(interpolated[:, None], qs[left] + weight[:, None] * (qs[right] - qs[left]), qs[nearest])
    rows = np.where(close | interpolated, order[nearest], -1)
    reasons: list[str | None] = [
        None
        if rows[i] >= 0
        else f"no joint state within {tolerance:g} s (nearest {gap[i]:.6g} s away)"
        + (
            f"; the robot moved {moved[i]:.3g} rad between the two around it"
            if still is not None and between[i]
            else ""
        )
        for i in range(len(sample_ns))
    ]
    return rows, q_at, interpolated, reasons


def _match_keys(controller_keys: np.ndarray, sensor_keys: np.ndarray) -> tuple[np.ndarray, list[str | None]]:
    """Controller row (or -1) of each sensor row, and why each unmatched one is."""
    index = {key: i for i, key in enumerate(controller_keys)}
    rows = np.array([index.get(key, -1) for key in sensor_keys], dtype=np.int64)
    return rows, [None if r >= 0 else "key not in the controller log" for r in rows]


def _match_times(
    controller_times: pd.DatetimeIndex,
    sensor_times: pd.DatetimeIndex,
    tolerance: float,
    controller_lines: np.ndarray,
    sensor_lines: np.ndarray,
) -> tuple[np.ndarray, list[str | None]]:
    """Controller row (or -1) of each sensor row: the nearest controller time (earlier one on a tie)
    within `tolerance` s; when several sensor rows pick one controller row the nearest keeps it."""
    ct = controller_times.asi8
    order = np.argsort(ct, kind="stable")
    sorted_ct = ct[order]
    st = sensor_times.asi8
    right = np.clip(np.searchsorted(sorted_ct, st), 0, len(ct) - 1)
    left = np.clip(right - 1, 0, len(ct) - 1)
    nearest = np.where(np.abs(st - sorted_ct[left]) <= np.abs(sorted_ct[right] - st), left, right)
    gap = np.abs(st - sorted_ct[nearest]) / 1e9  # s
    rows = np.where(gap <= tolerance, order[nearest], -1)
    reasons: list[str | None] = [
        None if r >= 0 else f"no controller time within {tolerance:g} s (nearest {gap[i]:.6g} s away)"
        for i, r in enumerate(rows)
    ]
    for row in np.unique(rows[rows >= 0]):
        claims = np.flatnonzero(rows == row)
        if claims.size > 1:
            winner = claims[np.lexsort((claims, gap[claims]))[0]]
            for loser in claims[claims != winner]:
                rows[loser] = -1
                reasons[loser] = (
                    f"controller line {controller_lines[row]} already matched by line "
                    f"{sensor_lines[winner]}, {gap[winner]:.6g} s from it (this row: {gap[loser]:.6g} s)"
                )
    return rows, reasons


# --------------------------------------------------------------------------- building


@dataclass(frozen=True, eq=False)
class ImportResult:
    """metadata: campaign.yaml content; tables: sensor -> contract table (SI), one row per controller
    row in log order; report: what was matched and what was not (lines 1-based)."""

    metadata: dict[str, Any]
    tables: dict[str, pd.DataFrame]
    report: dict[str, Any]
    sensor_rows: dict[str, np.ndarray]  # sensor -> (n_controller_rows,) row of its export per table row, -1 if none
    # sensor -> the controller log's row of each table row: the row itself, or a paired sample's joint state
    controller_rows: dict[str, np.ndarray]
    validation: ImportResult | None = None  # a validation bag's import (`joined`): the tables' rows after this one's


def _carried(export: Export, spec: FileSpec, where: str) -> dict[str, np.ndarray]:
    return {c: _numbers(export, c, f"{where}/carry", spec.decimal, allow_missing=True) for c in spec.carry}


def _controller_columns(spec: ImportSpec, export: Export) -> dict[str, Any]:
    """set, pose, solution, q1..qN (rad), carried columns, and key/time for matching."""
    c = spec.controller
    n = len(export.cells)
    if c.set is not None:
        sets = export.column(c.set, "controller/set").to_numpy(dtype=object)
        unknown = np.flatnonzero([s not in SETS for s in sets])
        if unknown.size:
            raise export.fail(c.set, f"unknown set (use {' or '.join(SETS)})", unknown)
    elif c.bag is not None and export.times is not None:  # a bag's joint states: its validation window
        sets = _window_sets(export.times, c.bag.validation)
    else:
        sets = np.full(n, SETS[0], dtype=object)
    if c.pose is not None:
        pose = _indices(export, c.pose, "controller/pose")
    else:  # each row its own pose, numbered within its set
        pose = pd.Series(sets).groupby(sets).cumcount().to_numpy(dtype=np.int64)
    solution = _indices(export, c.solution, "controller/solution") if c.solution is not None else np.zeros(n, np.int64)
    keys = pd.DataFrame({"set": sets, "pose": pose, "solution": solution})
    duplicated = np.flatnonzero(keys.duplicated(keep=False).to_numpy())
    if duplicated.size:
        named = ", ".join(x for x in (c.set, c.pose, c.solution) if x) or "row order"
        raise InputError(
            f"repeated (set, pose, solution) on {_lines(export.lines[duplicated])}: each may appear once",
            file=export.source,
            key=named,
        )
    columns: dict[str, Any] = {"set": sets, "pose": pose, "solution": solution}
    scale = ANGLE_UNITS[c.unit]
    for name, column in zip(joint_columns(len(c.joints)), c.joints):
        columns[name] = _numbers(export, column, "controller/joints", c.file.decimal, allow_missing=False) * scale
    matches = {s.match for s in spec.sensors.values()}
    key = _keys(export, c.key, "controller/key") if "key" in matches else None
    if export.times is not None:  # a bag's, as decoded
        time = export.times
    else:
        time = _times(export, c.time, "controller/time", c.file) if c.time is not None else None
    if time is not None and "time" in matches:
        repeated = np.flatnonzero(pd.Series(time).duplicated(keep=False).to_numpy())
        if repeated.size:
            raise export.fail(c.time, "repeated times (matching by time needs distinct times)", repeated)
    return {"columns": columns, "carry": _carried(export, c.file, "controller"), "key": key, "time": time}


def _positions(spec: SensorSpec, export: Export) -> np.ndarray:
    """The export's marker positions (n, 3) m, NaN where the marker was not seen; an error where
    some but not all of x, y, z are empty, or a position is beyond MAX_POSITION (a wrong unit)."""
    where = f"sensors/{spec.name}"
    xyz = (
        np.column_stack([_numbers(export, c, f"{where}/xyz", spec.file.decimal, allow_missing=True) for c in spec.xyz])
        * LENGTH_UNITS[spec.unit]
    )
    nan = np.isnan(xyz)
    partial = np.flatnonzero(nan.any(axis=1) & ~nan.all(axis=1))
    if partial.size:
        raise InputError(
            f"some but not all of x, y, z empty on {_lines(export.lines[partial])} "
            "(all three empty marks an unseen marker)",
            file=export.source,
            key=", ".join(spec.xyz),
        )
    too_far = np.flatnonzero(np.nan_to_num(np.abs(xyz)).max(axis=1) > MAX_POSITION)
    if too_far.size:
        raise InputError(
            f"marker positions beyond {MAX_POSITION:g} m on {_lines(export.lines[too_far])} with "
            f"unit {spec.unit}: is the unit right?",
            file=export.source,
            key=", ".join(spec.xyz),
        )
    return xyz


def _sensor_table(
    spec: SensorSpec,
    export: Export,
    controller: dict[str, Any],
    controller_export: Export,
    controller_spec: ControllerSpec,
) -> tuple[pd.DataFrame, dict[str, Any], np.ndarray, np.ndarray]:
    """One sensor's contract table, its section of the report, the export row and the controller
    log's row of each table row: a row per controller row, or per paired sample of a sensor topic."""
    if spec.bag is not None:
        return _paired_table(spec, export, controller, controller_export, controller_spec)
    where = f"sensors/{spec.name}"
    xyz = _positions(spec, export)
    orientations = _orientations(spec, export, xyz)
    sensor_time = (
        _times(export, spec.time, f"{where}/time", spec.file)
        if spec.time is not None and (spec.match == "time" or controller["time"] is None)
        else None
    )
    if spec.match == "key":
        matched_key = _keys(export, spec.key, f"{where}/key")
        rows, reasons = _match_keys(controller["key"], matched_key)
        label = "key"
        shown = matched_key
    else:
        rows, reasons = _match_times(
            controller["time"], sensor_time, spec.tolerance, controller_export.lines, export.lines
        )
        label = "time"
        shown = export.cells[spec.time].to_numpy(dtype=object)

    n = len(controller_export.cells)
    source_row = np.full(n, -1, dtype=np.int64)
    source_row[rows[rows >= 0]] = np.flatnonzero(rows >= 0)
    measured = source_row >= 0
    table = pd.DataFrame(controller["columns"])
    table["pose"] = table["pose"].astype(np.int64)
    table["solution"] = table["solution"].astype(np.int64)
    read = dict(zip(POSITION_COLUMNS, xyz.T)) | dict(
        zip(ORIENTATION_COLUMNS, () if orientations is None else orientations.T)
    )
    for column, values in read.items():  # a row no sensor row matched: NaN
        table[column] = np.where(measured, values[np.maximum(source_row, 0)], np.nan)
    if controller["time"] is not None:
        table[TIME_COLUMN] = controller["time"]
    elif sensor_time is not None:
        times = pd.Series(pd.NaT, index=range(n), dtype="datetime64[ns, UTC]")
        times[measured] = sensor_time[source_row[measured]]
        table[TIME_COLUMN] = times
    for name, values in controller["carry"].items():
        table[name] = values
    for name, values in _carried(export, spec.file, where).items():
        column = np.full(n, np.nan)
        column[measured] = values[source_row[measured]]
        table[name] = column

    controller_label = controller_spec.key if spec.match == "key" else controller_spec.time
    unseen = measured & np.isnan(table["x"].to_numpy())
    matched = (rows, source_row, measured, unseen)
    report = _match_report(spec, export, controller_export, controller_label, matched, (label, shown, reasons))
    return table, report, source_row, np.arange(n)


def _match_report(
    spec: SensorSpec, export: Export, controller_export: Export, controller_label: str, matched: tuple, shown_as: tuple
) -> dict[str, Any]:
    """A CSV sensor's section of the import report: its rows matched to the controller's, and which
    were not (`matched`: rows, source_row, measured, unseen as `_sensor_table` computes them;
    `shown_as`: the match's label, each sensor row's shown value, each unmatched row's reason)."""
    rows, source_row, measured, unseen = matched
    label, shown, reasons = shown_as
    controller_shown = controller_export.cells[controller_label].to_numpy(dtype=object)
    return {
        "file": export.source,
        "match": spec.match,
        "rows": int(len(export.cells)),
        "matched": int(measured.sum()),
        **({"tolerance_s": spec.tolerance} if spec.match == "time" else {}),
        "unmatched": [
            {"file": export.source, "line": int(export.lines[i]), label: str(shown[i]), "reason": reasons[i]}
            for i in np.flatnonzero(rows < 0)
        ],
        "not_measured": [
            {
                "file": controller_export.source,
                controller_export.row_name: int(controller_export.lines[i]),
                label: str(controller_shown[i]),
            }
            for i in np.flatnonzero(~measured)
        ],
        "marker_not_seen": [
            {"file": export.source, "line": int(export.lines[source_row[i]]), label: str(shown[source_row[i]])}
            for i in np.flatnonzero(unseen)
        ],
    }


def _paired_table(
    spec: SensorSpec,
    export: Export,
    controller: dict[str, Any],
    controller_export: Export,
    controller_spec: ControllerSpec,
) -> tuple[pd.DataFrame, dict[str, Any], np.ndarray, np.ndarray]:
    """A sensor topic's table: a row per sample paired with a joint state (`_pair`), in log-time
    order, its time the sample's; samples left unpaired are excluded and listed in the report. The
    validation set: the samples inside the controller's validation window."""
    xyz = _positions(spec, export)
    orientations = _orientations(spec, export, xyz)
    names = joint_columns(len(controller_spec.joints))
    q = np.column_stack([controller["columns"][c] for c in names])
    rows, q_at, interpolated, reasons = _pair(
        controller["time"].asi8, q, export.times.asi8, spec.tolerance, spec.bag.still
    )
    kept = np.flatnonzero(rows >= 0)
    if not kept.size:  # nothing to calibrate from: a wrong tolerance, or stamps on two clocks
        raise InputError(
            f"no sample has a joint state (controller/topic {controller_spec.bag.topic}) within "
            f"sensors/{spec.name}/tolerance {spec.tolerance:g} s; the first: {reasons[0]} (are both stamped on one clock? stamp: log takes the bag's log time of each)",
            file=export.source,
            key=spec.bag.topic,
        )
    times = export.times[kept]
    sets = _window_sets(times, controller_spec.bag.validation)
    table = pd.DataFrame(
        {
            "set": sets,
            "pose": pd.Series(sets).groupby(sets).cumcount().to_numpy(dtype=np.int64),
            "solution": np.zeros(len(kept), np.int64),
            **dict(zip(names, q_at[kept].T)),
            **dict(zip(POSITION_COLUMNS, xyz[kept].T)),
            **({} if orientations is None else dict(zip(ORIENTATION_COLUMNS, orientations[kept].T))),
        }
    )
    table[TIME_COLUMN] = times
    shown = export.cells[TIME_COLUMN].to_numpy(dtype=object)
    unpaired = np.flatnonzero(rows < 0)
    report = {
        "file": export.source,
        "topic": spec.bag.topic,
        "frame_id": export.frame_id,
        "stamp": spec.bag.stamp,
        "match": "time",
        "rows": int(len(export.cells)),
        "matched": int(kept.size),
        "interpolated": int(interpolated[kept].sum()),
        "excluded": int(unpaired.size),
        "validation": int((sets == SETS[1]).sum()),
        "tolerance_s": spec.tolerance,
        **({"still_rad": spec.bag.still} if spec.bag.still is not None else {}),
        "unmatched": [
            {"file": export.source, "message": int(export.lines[i]), "time": str(shown[i]), "reason": reasons[i]}
            for i in unpaired
        ],
        "marker_not_seen": [
            {"file": export.source, "message": int(export.lines[i]), "time": str(shown[i])}
            for i in kept[np.isnan(xyz[kept, 0])]
        ],
    }
    return table, report, kept, rows[kept]


def build_campaign(spec: ImportSpec, controller: Export, sensors: Mapping[str, Export]) -> ImportResult:
    """The campaign (metadata and SI tables) and the import report from a checked configuration and
    the exports it names (sensor name -> Export). Raises InputError naming file, column and line."""
    columns = _controller_columns(spec, controller)
    tables, sections, rows, controller_rows = {}, {}, {}, {}
    for name, sensor in spec.sensors.items():
        tables[name], sections[name], rows[name], controller_rows[name] = _sensor_table(
            sensor, sensors[name], columns, controller, spec.controller
        )
    report = {
        "campaign": spec.metadata["name"],
        "config": spec.source,
        "controller": {
            "file": controller.source,
            "rows": int(len(controller.cells)),
            "joint_unit": spec.controller.unit,
            **({"topic": spec.controller.bag.topic, "stamp": spec.controller.bag.stamp} if spec.controller.bag else {}),
            **(
                {"validation": dict(zip(WINDOW_KEYS, map(_utc, spec.controller.bag.validation)))}
                if spec.controller.bag and spec.controller.bag.validation
                else {}
            ),
        },
        "sensors": {name: {**section, "unit": spec.sensors[name].unit} for name, section in sections.items()},
        "unmatched_rows": sum(len(s["unmatched"]) for s in sections.values()),
    }
    return ImportResult(
        metadata=spec.metadata, tables=tables, report=report, sensor_rows=rows, controller_rows=controller_rows
    )


def in_exports(
    exc: InputError,
    sensor: str | None,
    spec: ImportSpec,
    result: ImportResult,
    controller: Export,
    sensors: Mapping[str, Export],
) -> InputError:
    """A problem the campaign reader found in the built campaign (in table `sensor`, or None for
    campaign.yaml), named in the exports' terms: the configuration for campaign.yaml, else the CSV
    file, its columns and 1-based lines."""
    if sensor not in spec.sensors:
        return type(exc)(exc.reason, file=spec.source, key=exc.key)
    keys = [k.strip() for k in (exc.key or "").split(",") if k.strip()]
    rows = np.asarray(exc.rows or [], dtype=np.int64)
    c = spec.controller
    if keys and all(k in POSITION_COLUMNS + ORIENTATION_COLUMNS for k in keys):
        # positions and orientations: columns and lines of the sensor's export, not the controller log's
        given = spec.sensors[sensor].orientation or ORIENTATION_COLUMNS
        export, names = sensors[sensor], dict(zip(POSITION_COLUMNS, spec.sensors[sensor].xyz))
        names |= (
            dict(zip(ORIENTATION_COLUMNS, given))
            if len(given) == 3
            else dict.fromkeys(ORIENTATION_COLUMNS, ", ".join(given))  # a quaternion's 4 columns give all three
        )
        source_rows = result.sensor_rows[sensor][rows]
        lines = export.lines[source_rows[source_rows >= 0]]
    else:  # everything else comes from the controller log, row for row
        export, lines = controller, controller.lines[result.controller_rows[sensor][rows]]
        names = {
            **dict(zip(joint_columns(len(c.joints)), c.joints)),
            **{k: getattr(c, k) or f"{k} (not a column: default)" for k in KEY_COLUMNS},
        }
    where = f" on {format_rows(lines, export.row_name)}" if len(lines) else ""
    return InputError(
        f"{exc.reason} (campaign table {sensor}){where}",
        file=export.source,
        key=", ".join(dict.fromkeys(names.get(k, k) for k in keys)) or None,
    )
