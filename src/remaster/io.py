"""Files: reading and writing campaign folders, YAML and JSON, importing exports. The only module
that touches paths.

A campaign folder is campaign.yaml plus one <sensor>.parquet per sensor (docs/campaign-format.md).
`read_campaign` checks the folder against that contract and returns a `remaster.campaigns.campaign.Campaign`.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import logging
import math
import re
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from .campaigns import importer
from .campaigns.campaign import (
    OPTIONAL_KEYS,
    REQUIRED_KEYS,
    SENSOR_NAME_PATTERN,
    Campaign,
    sensor_data,
    validate_metadata,
    validate_robot,
)
from .errors import InputError, KinematicsError, format_rows
from .robot.kinematics import KinematicChain, chain_from_dh, chain_from_urdf, max_chain_difference

log = logging.getLogger(__name__)

METADATA_FILE = "campaign.yaml"
SHARED_ROBOTS = Path("data") / "robots"  # under the repository root
CHAIN_CHECK_SEED = 20180612
CHAIN_CHECK_CONFIGURATIONS = 16
CHAIN_TOLERANCE = 1e-6  # m (and rad at a 1 m lever arm)


# --------------------------------------------------------------------------- YAML and JSON


def _plain(value: Any) -> Any:
    """Nested mappings/sequences of NumPy or Python values -> plain dicts, lists, floats, ints, str."""
    if isinstance(value, Mapping):
        return {str(k) if isinstance(k, Path) else k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


def read_yaml(path: str | Path) -> Any:
    """Content of a YAML file (yaml.safe_load); InputError naming the file if missing or malformed,
    or if it holds a tag plain YAML has no constructor for (e.g. !!python/object/apply)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("file not found", file=str(path)) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        tag = re.search(r"constructor for the tag '([^']*)'", str(getattr(exc, "problem", "")))
        if tag:  # e.g. !!python/object/apply: safe_load has no constructor for it
            mark = getattr(exc, "problem_mark", None)
            line = f"line {mark.line + 1}: " if mark is not None else ""
            raise InputError(f"{line}YAML tag {tag.group(1)!r} refused: remaster reads plain YAML (yaml.safe_load) "
                             f"and never builds objects from tags; nothing was executed", file=str(path)) from None
        raise InputError(f"not valid YAML: {exc}", file=str(path)) from None


def write_text(path: str | Path, text: str) -> Path:
    """Write text (UTF-8, newlines as given) to `path`, creating its folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8", newline="\n")
    return path


def write_yaml(path: str | Path, data: Any) -> Path:
    """Write `data` as block YAML, keys in the given order, leaf lists inline; same data, same bytes."""
    path = Path(path)
    text = yaml.safe_dump(_plain(data), sort_keys=False, allow_unicode=True, default_flow_style=None, width=100)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8", newline="\n")
    return path


def write_json(path: str | Path, data: Any) -> Path:
    """Write `data` as indented JSON with sorted keys and a final newline; same data, same bytes.

    NumPy values become plain numbers/lists, dates ISO strings; NaN and infinities become null,
    so the file is strict JSON that any reader accepts.
    """
    path = Path(path)

    def fallback(value: Any) -> Any:
        if isinstance(value, (dt.date, dt.datetime)):
            return value.isoformat()
        raise TypeError(f"cannot write {type(value).__name__} to JSON ({path})")

    text = json.dumps(_plain(data), sort_keys=True, indent=2, ensure_ascii=False, default=fallback, allow_nan=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text + "\n", encoding="utf-8", newline="\n")
    return path


def write_parquet(path: str | Path, table: pd.DataFrame) -> Path:
    """Write a table as Parquet without its index; same data, same bytes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_pandas(table, preserve_index=False), path)
    return path


def read_parquet(path: str | Path) -> pd.DataFrame:
    """A Parquet table; InputError naming the file if it cannot be read."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", file=str(path))
    return _read_parquet(path)


def read_json(path: str | Path) -> Any:
    """Content of a JSON file; InputError naming the file if missing or malformed."""
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("file not found", file=str(path)) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc}", file=str(path)) from None


def read_laplace(path: str | Path):
    """The Laplace report of a fit (`inference.fit.LaplaceReport`); InputError naming the file and
    the key when one is missing."""
    from .inference.fit import LaplaceReport

    return LaplaceReport.of(read_json(path), source=str(path))


def read_loop(path: str | Path):
    """The loop closure's report of a sensor (`loop.report.LoopReport`); InputError naming the
    file and the key when one is missing."""
    from .loop.report import LoopReport

    return LoopReport.of(read_json(path), source=str(path))


def read_registration(path: str | Path):
    """The initial registration of a sensor (`inference.fit.Registration`); InputError naming the
    file and the key when one is missing."""
    from .inference.fit import Registration

    return Registration.of(read_json(path), source=str(path))


def write_table(stem: str | Path, table: pd.DataFrame, caption: str, label: str) -> list[Path]:
    """Write a table as <stem>.csv, <stem>.md and <stem>.tex (see `remaster.reporting.tables`)."""
    from .reporting import tables

    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix(".csv"), stem.with_suffix(".md"), stem.with_suffix(".tex")]
    write_csv(paths[0], table)  # full precision: only the text forms are rounded
    paths[1].write_text(f"**{caption}**\n\n" + tables.to_markdown(table), encoding="utf-8", newline="\n")
    paths[2].write_text(tables.to_latex(table, caption, label), encoding="utf-8", newline="\n")
    return paths


def write_figure(stem: str | Path, figure) -> list[Path]:
    """Save a matplotlib figure as <stem>.png and <stem>.pdf, reproducibly (no timestamps), and close it."""
    import matplotlib.pyplot as plt

    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix(".png"), stem.with_suffix(".pdf")]
    figure.savefig(paths[0], dpi=120, metadata={"Software": None})
    figure.savefig(paths[1], metadata={"Creator": None, "Producer": None, "CreationDate": None})
    plt.close(figure)
    return paths


def file_digests(paths, relative_to_parent: bool = False) -> dict[str, str]:
    """SHA-256 of each file, keyed by its path (or by its name within its folder)."""
    import hashlib

    out = {}
    for path in map(Path, paths):
        key = path.name if relative_to_parent else str(path)
        out[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def read_csv(path: str | Path) -> pd.DataFrame:
    """A CSV table; InputError naming the file if it is missing or unreadable."""
    path = Path(path)
    try:
        return pd.read_csv(path)
    except FileNotFoundError:
        raise InputError("file not found", file=str(path)) from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=str(path)) from None


def write_csv(path: str | Path, table: pd.DataFrame) -> Path:
    """Write a table as CSV without its index, floats at full precision; same data, same bytes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(path, index=False, float_format="%.17g", lineterminator="\n")
    return path


@contextlib.contextmanager
def log_to(path: str | Path, level: int = logging.INFO):
    """Send remaster's log records to `path` for the duration; an exception is logged with its
    traceback before it propagates, so a failed workflow job's log says why."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(path, mode="w", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    logger = logging.getLogger("remaster")
    logger.addHandler(handler)
    previous = logger.level
    logger.setLevel(level)
    try:
        yield logger
    except Exception:
        logger.exception("failed")
        raise
    finally:
        logger.removeHandler(handler)
        logger.setLevel(previous)
        handler.close()


# --------------------------------------------------------------------------- robot


def _urdf_candidates(urdf: str, folder: Path, repo_root: Path) -> list[Path]:
    """Where a campaign's `robot/urdf` may live, in the order they are tried."""
    candidates = [folder / urdf, repo_root / urdf, repo_root / SHARED_ROBOTS / Path(urdf).name]
    return list(dict.fromkeys(candidates))


def robot_section(folder: str | Path) -> Mapping:
    """campaign.yaml's `robot` section as written, for planning a workflow before the campaign is
    read; {} when it does not parse (reading the campaign says why, with file and key)."""
    try:
        robot = yaml.safe_load((Path(folder) / "campaign.yaml").read_text(encoding="utf-8")).get("robot")
    except (OSError, yaml.YAMLError, AttributeError):
        return {}
    return robot if isinstance(robot, Mapping) else {}


def robot_files(folder: str | Path, repo_root: str | Path = ".") -> list[Path]:
    """The robot description files a campaign folder's campaign.yaml refers to outside the folder
    (its URDF, found as `load_chain` finds it), so that a workflow can declare and hash them; []
    when there are none or campaign.yaml does not parse (reading the campaign says why)."""
    folder = Path(folder)
    urdf = robot_section(folder).get("urdf")
    if not isinstance(urdf, str):
        return []
    found = next((p for p in _urdf_candidates(urdf, folder, Path(repo_root)) if p.is_file()), None)
    return [] if found is None or found.resolve().parent == folder.resolve() else [found]


def package_digests() -> dict[str, str]:
    """SHA-256 of every source file of the installed remaster package, keyed by its path in it:
    the code that made a result, identified by content."""
    root = Path(__file__).resolve().parent
    files = sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts)
    return {str(p.relative_to(root)): digest for p, digest in zip(files, file_digests(files).values())}


def git_commit(repo_root: str | Path = ".") -> dict | None:
    """{'commit', 'dirty'} of the git checkout at repo_root, None outside one (or without git)."""
    import subprocess

    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo_root, capture_output=True, text=True,
                                timeout=30)
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=repo_root,
                                capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    if commit.returncode != 0:
        return None
    return {"commit": commit.stdout.strip(), "dirty": bool(status.stdout.strip())}


def _in_robot_section(exc: KinematicsError, source: str, note: str = "") -> KinematicsError:
    """The same problem, reported against campaign.yaml's robot/<key>."""
    key = f"robot/{exc.key}" if exc.key else "robot"
    return KinematicsError(exc.reason + note, file=source, key=key, rows=exc.rows)


def load_chain(robot_meta: Mapping[str, Any], folder: str | Path, repo_root: str | Path | None = None, *,
               source: str | None = None, name: str = "dh_robot") -> KinematicChain:
    """The kinematic chain of a campaign's `robot` section.

    `urdf` is looked for relative to `folder`, then to `repo_root` (default: the current
    directory), then as repo_root/data/robots/<file name>; `base`/`flange` are its links. `dh`
    builds a chain from DH rows (named `name`). When both are given they must agree to
    CHAIN_TOLERANCE on the flange pose over fixed-seed random configurations within +-pi; the
    URDF chain (joint names, limits, masses) is returned. `source` names campaign.yaml in errors.
    """
    folder = Path(folder)
    repo_root = Path.cwd() if repo_root is None else Path(repo_root)
    source = str(folder / METADATA_FILE) if source is None else source
    robot = validate_robot(robot_meta, source)

    urdf_chain = dh_chain = None
    if "urdf" in robot:
        candidates = _urdf_candidates(robot["urdf"], folder, repo_root)
        urdf_path = next((p for p in candidates if p.is_file()), None)
        if urdf_path is None:
            raise KinematicsError(f"URDF file {robot['urdf']!r} not found (looked for "
                                  f"{', '.join(str(p) for p in candidates)})", file=source, key="robot/urdf")
        try:
            urdf_chain = chain_from_urdf(urdf_path.read_text(encoding="utf-8"), robot.get("base"),
                                         robot.get("flange"), source=str(urdf_path))
        except KinematicsError as exc:
            if exc.key not in ("base", "flange"):
                raise
            raise _in_robot_section(exc, source, f" (URDF {urdf_path})") from None
    if "dh" in robot:
        dh = robot["dh"]
        try:
            dh_chain = chain_from_dh(dh["rows"], dh["convention"], dh.get("flange"), name=name, source=source)
        except KinematicsError as exc:
            raise _in_robot_section(exc, source) from None
    if urdf_chain is None or dh_chain is None:
        return urdf_chain or dh_chain

    if urdf_chain.n_joints != dh_chain.n_joints:
        raise KinematicsError(f"urdf and dh describe different robots: the URDF chain has {urdf_chain.n_joints} "
                              f"joints, the DH table {dh_chain.n_joints} rows", file=source, key="robot")
    rng = np.random.default_rng(CHAIN_CHECK_SEED)
    q = rng.uniform(-math.pi, math.pi, size=(CHAIN_CHECK_CONFIGURATIONS, urdf_chain.n_joints))
    difference = max_chain_difference(urdf_chain, dh_chain, q)
    if not difference <= CHAIN_TOLERANCE:
        raise KinematicsError(f"urdf and dh describe different chains: flange poses differ by up to "
                              f"{difference * 1e3:.4g} mm (tolerance {CHAIN_TOLERANCE * 1e3:g} mm)",
                              file=source, key="robot")
    return urdf_chain


# --------------------------------------------------------------------------- campaigns


def _read_parquet(path: Path) -> pd.DataFrame:
    try:
        return pd.read_parquet(path)
    except (OSError, pa.ArrowException, ValueError) as exc:
        raise InputError(f"cannot read Parquet: {exc}", file=str(path)) from None


def campaign_folders(files) -> dict[str, Path]:
    """{campaign name: folder} of the campaign.yaml files among a job's declared input files: a
    workflow job reads the campaigns it declares, and finds their folders from them."""
    return {path.parent.name: path.parent for path in map(Path, files) if path.name == METADATA_FILE}


def campaign_folder(files) -> Path:
    """The folder of the one campaign whose files a job declares (`campaign_folders`)."""
    folders = campaign_folders(files)
    if len(folders) != 1:
        raise InputError(f"a job's campaign files hold {len(folders)} {METADATA_FILE} files, not one",
                         file=", ".join(map(str, files)) or "(no input files)")
    return next(iter(folders.values()))


def read_campaign(folder: str | Path, repo_root: str | Path | None = None) -> Campaign:
    """Read and validate a campaign folder (campaign.yaml + one <sensor>.parquet per sensor).

    `repo_root` (default: the current directory) is where shared URDFs are looked for. Raises
    InputError (KinematicsError for the robot model) naming the file, key/column and rows.
    Rows whose marker was not seen (x, y, z NaN) are kept and logged.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a campaign folder (no such directory)", file=str(folder))
    source = str(folder / METADATA_FILE)
    meta = validate_metadata(read_yaml(folder / METADATA_FILE), source)
    folder_name = folder.resolve().name
    if meta["name"] != folder_name:
        raise InputError(f"is {meta['name']!r} but the folder is named {folder_name!r}; they must be equal",
                         file=source, key="name")
    chain = load_chain(meta["robot"], folder, repo_root, source=source, name=meta["name"])

    tables = {path.stem: path for path in sorted(folder.glob("*.parquet"))}
    for sensor in meta["sensors"]:
        if sensor not in tables:
            raise InputError(f"no file {sensor}.parquet in {folder}", file=source, key=f"sensors/{sensor}")
    for stem, path in tables.items():
        if stem not in meta["sensors"]:
            raise InputError(f"no sensor {stem!r} under `sensors` in {source}: name it there or remove the file",
                             file=str(path), key="sensors")

    sensors = {}
    for sensor, spec in meta["sensors"].items():
        path = tables[sensor]
        sensors[sensor] = sensor_data(sensor, spec, _read_parquet(path), chain.n_joints, str(path),
                                      limits=(chain.lower, chain.upper))
        if sensors[sensor].n_missing:
            log.info("%s: %d of %d rows without a measurement (marker not seen: %s)", path,
                     sensors[sensor].n_missing, len(sensors[sensor].table), format_rows(sensors[sensor].missing_rows))
    return Campaign(name=meta["name"], date=meta["date"], description=meta["description"],
                    robot=_plain(meta["robot"]), chain=chain, sensors=sensors)


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
            raise InputError("a sensor name must be a file stem (letters, digits, _ . -)", file=str(folder),
                             key=f"sensors/{sensor}")
    folder.mkdir(parents=True, exist_ok=True)
    order = [k for k in REQUIRED_KEYS[:2] + OPTIONAL_KEYS + REQUIRED_KEYS[2:] if k in metadata]
    write_yaml(folder / METADATA_FILE, {**{k: metadata[k] for k in order},
                                        **{k: v for k, v in metadata.items() if k not in order}})
    for sensor, table in tables.items():
        pq.write_table(pa.Table.from_pandas(table, preserve_index=False), folder / f"{sensor}.parquet")
    return folder


# --------------------------------------------------------------------------- imports


def read_export(path: str | Path, delimiter: str = ",") -> importer.Export:
    """`importer.parse_csv` of a file (UTF-8, with or without a byte-order mark)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError("file not found", file=str(path)) from None
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text: {exc}", file=str(path)) from None
    return importer.parse_csv(text, str(path), delimiter)


def _local_urdf(robot: Mapping[str, Any], config_dir: Path, repo_root: Path) -> Path | None:
    """The URDF to copy into the campaign folder: one found next to the configuration only
    (not under the repository root, nor shared in data/robots)."""
    if "urdf" not in robot:
        return None
    urdf = robot["urdf"]
    if (repo_root / urdf).is_file() or (repo_root / SHARED_ROBOTS / Path(urdf).name).is_file():
        return None
    return config_dir / urdf if (config_dir / urdf).is_file() else None


def import_campaign(config_path: str | Path, raw_dir: str | Path, repo_root: str | Path | None = None,
                    overwrite: bool = False) -> tuple[Path, dict[str, Any]]:
    """`remaster import`: read an import configuration (format: `remaster.campaigns.importer`) and its CSV
    files, write <raw_dir>/<name>/ (campaign.yaml, one <sensor>.parquet per sensor, the URDF when
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
        raise InputError(f"names {len(spec.controller.joints)} joint columns but the robot has {chain.n_joints} joints",
                         file=source, key="controller/joints")

    def export(file: importer.FileSpec) -> importer.Export:
        return read_export(config_dir / file.file, file.delimiter)

    controller, sensors = export(spec.controller.file), {n: export(s.file) for n, s in spec.sensors.items()}
    result = importer.build_campaign(spec, controller, sensors)
    metadata = result.metadata
    urdf = _local_urdf(metadata["robot"], config_dir, repo_root)
    if urdf is not None:
        metadata = {**metadata, "robot": {**metadata["robot"], "urdf": urdf.name}}

    folder = Path(raw_dir) / metadata["name"]
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise InputError("the campaign folder exists already (import with overwrite / --force to replace it)",
                         file=str(folder))
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
            raise importer.in_exports(exc, sensor, spec, result, controller, sensors) from None
        write_json(staged / importer.REPORT_FILE, result.report)
        folder.mkdir(parents=True, exist_ok=True)
        for old in [folder / METADATA_FILE, folder / importer.REPORT_FILE, *folder.glob("*.parquet")]:
            old.unlink(missing_ok=True)
        for path in sorted(staged.iterdir()):
            shutil.copyfile(path, folder / path.name)
    return folder, result.report


# --------------------------------------------------------------------------- one sensor's results

SENSOR_RESULTS = {  # what `remaster predict` and `remaster compensate` read of `snakemake -j2`'s results
    "registration": "registration.json", "laplace": "fit/laplace.json", "summary": "fit/summary.csv",
    "paper_samples": "fit/samples_default.parquet", "loop": "loop_closure.json",
    "loop_samples": "loop_closure/samples.parquet", "gp": "loop_closure/residual_gp.parquet"}


def read_sensor_results(results_dir: str | Path, campaign: str, sensor: str) -> dict[str, Any]:
    """The results of one campaign's sensor (`SENSOR_RESULTS`, under results_dir/campaign/sensor)
    by key; InputError naming the folder or file when the workflow has not written them."""
    folder = Path(results_dir) / campaign / sensor
    if not folder.is_dir():
        raise InputError("no results of this campaign and sensor: run `snakemake -j2` first, or give the results "
                         "folder it wrote", file=str(folder))
    readers = {".json": read_json, ".csv": read_csv, ".parquet": read_parquet, "laplace": read_laplace,
               "registration": read_registration, "loop": read_loop}
    return {key: readers.get(key, readers[Path(name).suffix])(folder / name) for key, name in SENSOR_RESULTS.items()}
