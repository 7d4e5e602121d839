"""Campaign folders on disk: reading and checking one, writing one, finding a job's, and importing
a controller's and sensors' CSV exports (or a ROS 2 bag of the controller's joint states) into one.

A campaign folder is campaign.yaml plus one <sensor>.parquet per sensor (docs/campaign-format.md).
`read_campaign` checks the folder against that contract and returns a `campaign.Campaign`.
"""

from __future__ import annotations

import logging
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import provenance
from ..errors import InputError, format_rows, quoted
from ..files import plain, read_parquet, read_text, read_yaml, write_json, write_parquet, write_yaml
from ..layout import CAMPAIGN_FILE, SHARED_ROBOTS
from . import importer
from .campaign import (
    OPTIONAL_KEYS,
    REQUIRED_KEYS,
    SENSOR_NAME_PATTERN,
    Campaign,
    sensor_data,
    summarize,
    validate_metadata,
)
from .robot_model import load_chain, robot_files

log = logging.getLogger(__name__)


def campaign_folders(files) -> dict[str, Path]:
    """{campaign name: folder} of the campaign.yaml files among a job's declared input files: a
    workflow job reads the campaigns it declares, and finds their folders from them."""
    return {path.parent.name: path.parent for path in map(Path, files) if path.name == CAMPAIGN_FILE}


def campaign_folder(files) -> Path:
    """The folder of the one campaign whose files a job declares (`campaign_folders`)."""
    folders = campaign_folders(files)
    if len(folders) != 1:
        raise InputError(
            f"a job's campaign files hold {len(folders)} {CAMPAIGN_FILE} files, not one",
            file=", ".join(map(str, files)) or "(no input files)",
        )
    return next(iter(folders.values()))


def campaign_files(folder: str | Path, repo_root: str | Path = ".") -> list[Path]:
    """The files a campaign is read from: campaign.yaml, its Parquet tables, a URDF in its folder
    and the robot description it names outside it (a shared URDF, found from `repo_root`). The
    workflow declares them as a campaign's inputs (changing one reruns that campaign's jobs only)
    and the audit hashes them; a README or licence beside them is not an input."""
    folder = Path(folder)
    inside = [folder / CAMPAIGN_FILE, *sorted(folder.glob("*.parquet")), *sorted(folder.glob("*.urdf"))]
    return inside + robot_files(folder, repo_root)


def outside_inputs(folder: str | Path, repo_root: str | Path = ".") -> list[str]:
    """The campaign's input files (`campaign_files`) that resolve outside its folder: a shared robot
    description named by a relative or absolute path, a symbolic link to a file elsewhere; each as
    `<name in the campaign> -> <resolved path>`. The audit hashes them like the others; a reader of
    the certificate learns that the campaign alone does not reproduce its results."""
    home = Path(folder).resolve()
    out = []
    for path in campaign_files(folder, repo_root):
        target = Path(path).resolve()
        if home not in target.parents:
            out.append(f"{Path(path).name} -> {target}")
    return out


def summarize_folder(
    folder: str | Path, memory_limit: float | None = None, draws: int = 2000, fit_rows: int = 0
) -> dict:
    """`campaign.summarize` of the campaign read from `folder`, with the inputs it reads from outside
    the folder (`outside_inputs`, under `inputs_outside_the_folder`)."""
    summary = summarize(read_campaign(folder), memory_limit, draws, fit_rows)
    return {**summary, "inputs_outside_the_folder": outside_inputs(folder)}


def campaign_digests(folder: str | Path, repo_root: str | Path = ".") -> dict[str, str]:
    """{file name: SHA-256} of `campaign_files`, keyed by name so that the same campaign copied
    elsewhere has the same digests: what the audit records of a campaign (`audit.folder_digest` of
    it is the campaign's content hash, `content_sha256`)."""
    return provenance.file_digests(campaign_files(folder, repo_root), relative_to_parent=True)


def read_campaign(folder: str | Path, repo_root: str | Path | None = None) -> Campaign:
    """Read and validate a campaign folder (campaign.yaml + one <sensor>.parquet per sensor).

    `repo_root` (default: the current directory) is where shared URDFs are looked for. Raises
    InputError (KinematicsError for the robot model) naming the file, key/column and rows.
    Rows whose marker was not seen (x, y, z NaN) are kept and logged.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a campaign folder (no such directory)", file=str(folder))
    source = str(folder / CAMPAIGN_FILE)
    meta = validate_metadata(read_yaml(folder / CAMPAIGN_FILE), source)
    folder_name = folder.resolve().name
    if meta["name"] != folder_name:
        raise InputError(
            f"is {quoted(meta['name'])} but the folder is named {quoted(folder_name)}; they must be equal",
            file=source,
            key="name",
        )
    chain = load_chain(meta["robot"], folder, repo_root, source=source, name=meta["name"])

    tables = {path.stem: path for path in sorted(folder.glob("*.parquet"))}
    for sensor in meta["sensors"]:
        if sensor not in tables:
            raise InputError(f"no file {sensor}.parquet in {folder}", file=source, key=f"sensors/{sensor}")
    for stem, path in tables.items():
        if stem not in meta["sensors"]:
            raise InputError(
                f"no sensor {stem!r} under `sensors` in {source}: name it there or remove the file",
                file=str(path),
                key="sensors",
            )

    sensors = {}
    for sensor, spec in meta["sensors"].items():
        path = tables[sensor]
        sensors[sensor] = sensor_data(
            sensor,
            spec,
            read_parquet(path),
            chain.n_joints,
            str(path),
            limits=(chain.lower, chain.upper),
            metadata_source=source,
        )
        if sensors[sensor].n_missing:
            log.info(
                "%s: %d of %d rows without a measurement (marker not seen: %s)",
                path,
                sensors[sensor].n_missing,
                len(sensors[sensor].table),
                format_rows(sensors[sensor].missing_rows),
            )
    return Campaign(
        name=meta["name"],
        date=meta["date"],
        description=meta["description"],
        robot=plain(meta["robot"]),
        chain=chain,
        sensors=sensors,
        tools=meta["tools"],
    )


def write_campaign(folder: str | Path, metadata: Mapping[str, Any], tables: Mapping[str, pd.DataFrame]) -> Path:
    """Write campaign.yaml and one <sensor>.parquet per table into `folder` (created if needed).

    Deterministic: the same input gives byte-identical files. Top-level keys are written in the
    contract's order (name, date, description, robot, sensors, then anything else), tables with
    pyarrow and no pandas index. Does not validate (read the folder back with `read_campaign`),
    and does not delete other files already in the folder.
    """
    folder = Path(folder)
    for sensor in tables:
        if not isinstance(sensor, str) or not SENSOR_NAME_PATTERN.fullmatch(sensor):
            raise InputError(
                "a sensor name must be a file stem (letters, digits, _ . -)", file=str(folder), key=f"sensors/{sensor}"
            )
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a read-only --raw-dir: named, not a traceback
        raise InputError(f"cannot write the campaign folder: {exc.strerror or exc}", file=str(folder)) from None
    order = [k for k in REQUIRED_KEYS[:2] + OPTIONAL_KEYS + REQUIRED_KEYS[2:] if k in metadata]
    write_yaml(
        folder / CAMPAIGN_FILE,
        {**{k: metadata[k] for k in order}, **{k: v for k, v in metadata.items() if k not in order}},
    )
    for sensor, table in tables.items():
        write_parquet(folder / f"{sensor}.parquet", table)
    return folder


# --------------------------------------------------------------------------- imports


def read_export(path: str | Path, delimiter: str = ",") -> importer.Export:
    """`importer.parse_csv` of a file (UTF-8, with or without a byte-order mark)."""
    return importer.parse_csv(read_text(path, "utf-8-sig"), str(path), delimiter)


def read_bags(
    config_dir: Path, spec: importer.ImportSpec, controller_key: str = "controller/bag"
) -> tuple[importer.Export | None, dict[str, importer.Export]]:
    """The bags an import names (MCAP or sqlite3, `bags.read_topics`), each read once for all its
    topics: the controller's joint states (`importer.joint_state_export`; None for a CSV log) and
    each sensor topic's samples (`importer.measurement_export`). InputError naming the file when it
    is missing, a folder (a rosbag2 folder: name the .mcap or .db3 file in it) or unreadable."""
    from . import bags  # the bag readers, loaded only by an import from a bag

    wanted: dict[str, dict[str, tuple[str, ...]]] = {}  # bag as written -> topic -> the types accepted
    named_by: dict[str, str] = {}  # bag as written -> the first key naming it, for a missing file
    if spec.controller.bag is not None:
        wanted.setdefault(spec.controller.file.file, {})[spec.controller.bag.topic] = (bags.JOINT_STATE,)
        named_by[spec.controller.file.file] = controller_key
    for sensor in spec.sensors.values():
        if sensor.bag is not None:
            named_by.setdefault(sensor.file.file, f"sensors/{sensor.name}/bag")
            on_bag = wanted.setdefault(sensor.file.file, {})
            if on_bag.get(sensor.bag.topic, bags.MEASUREMENTS) != bags.MEASUREMENTS:
                raise InputError(
                    "is the controller's joint-state topic too", file=spec.source, key=f"sensors/{sensor.name}/topic"
                )
            on_bag[sensor.bag.topic] = bags.MEASUREMENTS
    read = {}
    for file, topics in wanted.items():
        path = config_dir / file
        if path.is_dir():
            inside = ", ".join(sorted(p.name for p in [*path.glob("*.mcap"), *path.glob("*.db3")])) or "none in it"
            raise InputError(
                f"is a folder, not a bag file: name the .mcap or .db3 file (found: {inside})", file=str(path)
            )
        try:
            read[file] = bags.read_topics(path, topics, str(path))
        except FileNotFoundError:
            raise InputError(f"file not found (the bag named by {named_by[file]})", file=str(path)) from None
        except OSError as exc:
            raise InputError(f"cannot read: {exc.strerror or exc}", file=str(path)) from None
    c = spec.controller
    controller = (
        None
        if c.bag is None
        else importer.joint_state_export(
            bags.joint_states(read[c.file.file][c.bag.topic]), c, str(config_dir / c.file.file)
        )
    )
    sensors = {
        name: importer.measurement_export(
            bags.measurements(read[s.file.file][s.bag.topic], s.bag.child_frame), s, str(config_dir / s.file.file)
        )
        for name, s in spec.sensors.items()
        if s.bag is not None
    }
    return controller, sensors


def _in_exports(exc: InputError, sensor: str | None, parts: list) -> InputError:
    """`importer.in_exports` of the part of the campaign the rows of a reader's error are in: the
    import's (spec, result, controller, sensors), or its validation bag's, whose rows follow."""
    spec, result, controller, sensors = parts[0]
    rows = np.asarray(exc.rows or [], dtype=np.int64)
    if len(parts) > 1 and sensor in spec.sensors and rows.size:
        first = len(result.sensor_rows[sensor])
        if (rows >= first).all():
            exc = InputError(exc.reason, file=exc.file, key=exc.key, rows=rows - first)
            spec, result, controller, sensors = parts[1]
        else:
            exc = InputError(exc.reason, file=exc.file, key=exc.key, rows=rows[rows < first])
    return importer.in_exports(exc, sensor, spec, result, controller, sensors)


def _local_urdf(robot: Mapping[str, Any], config_dir: Path, repo_root: Path) -> Path | None:
    """The URDF to copy into the campaign folder: one found next to the configuration only
    (not under the repository root, nor shared in data/robots)."""
    if "urdf" not in robot:
        return None
    urdf = robot["urdf"]
    if (repo_root / urdf).is_file() or (repo_root / SHARED_ROBOTS / Path(urdf).name).is_file():
        return None
    return config_dir / urdf if (config_dir / urdf).is_file() else None


def import_campaign(
    config_path: str | Path, raw_dir: str | Path, repo_root: str | Path | None = None, overwrite: bool = False
) -> tuple[Path, dict[str, Any]]:
    """`remaster import`: read an import configuration (format: `remaster.campaigns.importer`) and its CSV
    files (or the ROS 2 bags it names), write <raw_dir>/<name>/ (campaign.yaml, one <sensor>.parquet per sensor, the URDF when
    it lies only next to the configuration, and importer.REPORT_FILE), validated by reading it back
    with `read_campaign`. Returns (folder, report).

    `repo_root` (default: the current directory) is where shared URDFs are looked for. An existing
    non-empty folder is an error unless `overwrite`, which replaces its campaign.yaml, *.parquet and
    import report. Nothing is written when anything fails: the folder is built in a temporary
    place and copied only once it reads back.
    """
    config_path = Path(config_path)
    repo_root = Path.cwd() if repo_root is None else Path(repo_root)
    source = str(config_path)
    spec = importer.parse_config(read_yaml(config_path), source)
    config_dir = config_path.parent
    chain = load_chain(spec.metadata["robot"], config_dir, repo_root, source=source, name=spec.metadata["name"])
    if chain.n_joints != len(spec.controller.joints):
        raise InputError(
            f"names {len(spec.controller.joints)} joint columns but the robot has {chain.n_joints} joints",
            file=source,
            key="controller/joints",
        )

    def export(file: importer.FileSpec) -> importer.Export:
        return read_export(config_dir / file.file, file.delimiter)

    controller, sensors = read_bags(config_dir, spec)
    controller = controller or export(spec.controller.file)
    sensors |= {n: export(s.file) for n, s in spec.sensors.items() if s.bag is None}
    result = importer.build_campaign(spec, controller, sensors)
    parts = [(spec, result, controller, sensors)]  # the import's, then its validation bag's
    if spec.controller.bag is not None and spec.controller.bag.validation_bag is not None:
        second = importer.validation_spec(spec)
        second_controller, second_sensors = read_bags(config_dir, second, "controller/validation/bag")
        second_result = importer.build_campaign(second, second_controller, second_sensors)
        parts.append((second, second_result, second_controller, second_sensors))
        result = importer.joined(result, second_result)
    metadata = result.metadata
    urdf = _local_urdf(metadata["robot"], config_dir, repo_root)
    if urdf is not None:
        metadata = {**metadata, "robot": {**metadata["robot"], "urdf": urdf.name}}

    folder = Path(raw_dir) / metadata["name"]
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise InputError(
            "the campaign folder exists already (import with overwrite / --force to replace it)", file=str(folder)
        )
    with tempfile.TemporaryDirectory() as tmp:
        staged = Path(tmp) / metadata["name"]
        write_campaign(staged, metadata, result.tables)
        if urdf is not None:
            shutil.copyfile(urdf, staged / urdf.name)
        try:
            read_campaign(staged, repo_root)
        except InputError as exc:
            path = Path(exc.file) if exc.file else None
            sensor = path.stem if path is not None and path.parent == staged and path.suffix == ".parquet" else None
            raise _in_exports(exc, sensor, parts) from None
        write_json(staged / importer.REPORT_FILE, result.report)
        try:
            folder.mkdir(parents=True, exist_ok=True)
            for old in [folder / CAMPAIGN_FILE, folder / importer.REPORT_FILE, *folder.glob("*.parquet")]:
                old.unlink(missing_ok=True)
            for path in sorted(staged.iterdir()):
                shutil.copyfile(path, folder / path.name)
        except OSError as exc:  # a read-only --raw-dir: named, not a traceback
            raise InputError(f"cannot write the campaign folder: {exc.strerror or exc}", file=str(folder)) from None
    return folder, result.report
