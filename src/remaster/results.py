"""The one reader of the results the workflow wrote: the command line (`remaster predict`,
`compensate`, `plan --from-results`) and the workflow's scripts read a stage's files back through it.

A result is named by its key, the name the workflow's rules give the input (and `layout.SENSOR_RESULTS`
the file under a sensor's results folder): the registration, the Laplace fit and the loop closure's
report come back typed (`fit.Registration`, `laplace_report.LaplaceReport`, `LoopReport`), every other file as
its suffix says (JSON or YAML content, a CSV or Parquet table). A file not there is an InputError
naming it and what to run.

The results folder's integrity is kept here too: results are used only with the campaign, and as
the content, the audit recorded (`check_made_from`); one run writes a folder at a time
(`take_lock`, `release_lock`); after a failed run, the reports whose results failed go
(`stale_reports`).
"""

from __future__ import annotations

import json
import logging
import os
import re
import socket
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from . import audit, layout
from .campaigns.folders import campaign_digests
from .errors import InputError, listed
from .files import read_csv, read_json, read_parquet, read_yaml
from .inference.fit import Registration
from .inference.laplace_report import LaplaceReport
from .loop.result import LoopReport

TYPED = {"registration": Registration.read, "laplace": LaplaceReport.read, "loop": LoopReport.read}
BY_SUFFIX = {".json": read_json, ".yaml": read_yaml, ".csv": read_csv, ".parquet": read_parquet}
NOT_WRITTEN = "not written: run `snakemake -j2` on the campaign first"
NO_RESULTS = "no results of this campaign and sensor: run `snakemake -j2` first, or give the results folder it wrote"


def read_result(key: str, path: str | Path) -> Any:
    """The result `key` from its file `path` (module docstring); InputError naming the file when it
    is not there, unreadable, or a report without a key the later stages read."""
    path = Path(path)
    if not path.is_file():
        raise InputError(NOT_WRITTEN, file=str(path))
    if key in TYPED:
        return TYPED[key](path)
    if path.suffix not in BY_SUFFIX:
        raise InputError(f"no reader for a {path.suffix or 'suffix-less'} file", file=str(path))
    return BY_SUFFIX[path.suffix](path)


def read_results(paths: Mapping[str, str | Path], keys: Iterable[str] | None = None) -> dict[str, Any]:
    """{key: `read_result`} of the files paths[key] (e.g. a workflow job's named inputs), for every
    key of `keys` (default: every key of paths)."""
    return {key: read_result(key, paths[key]) for key in (paths if keys is None else keys)}


def sensor_folder(results_dir: str | Path, campaign: str, sensor: str) -> Path:
    """The results folder of one campaign's sensor: results_dir/layout.SENSOR_FOLDER."""
    return Path(results_dir) / layout.SENSOR_FOLDER.format(campaign=campaign, sensor=sensor)


def sensor_results(folder: str | Path, keys: Iterable[str] | None = None) -> dict[str, Any]:
    """{key: `read_result`} of the results in a sensor's results folder (`sensor_folder`) named by
    `keys` of `layout.SENSOR_RESULTS` (default every one); InputError naming the folder when the
    workflow has not filled it, or the first file it has not written."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(NO_RESULTS, file=str(folder))
    keys = list(layout.SENSOR_RESULTS if keys is None else keys)
    return read_results({key: folder / layout.SENSOR_RESULTS[key] for key in keys})


def _changed_results(results_dir: Path, recorded: Mapping | None, made_in: str | None) -> list[str]:
    """The result files (paths under results_dir) whose content is no longer the one whose SHA-256
    the audit recorded; a recorded file no longer there is left to its reader (`NOT_WRITTEN`)."""
    if not isinstance(recorded, Mapping) or not made_in:
        return []
    changed = []
    for made, digest in sorted(recorded.items()):
        try:
            relative = Path(made).relative_to(made_in)
        except ValueError:
            continue
        file = results_dir / relative
        if file.is_file() and audit.sha256(file.read_bytes()) != digest:
            changed.append(str(relative))
    return changed


def check_made_from(results_dir: str | Path, campaign_folder: str | Path, repo_root: str | Path = ".") -> None:
    """InputError unless the campaign folder is, byte for byte, the campaign the results in
    `results_dir` were made from: its content hash (`campaigns.folders.campaign_digests`, as the
    audit computes it) equal to the one results_dir/layout.AUDIT recorded. A campaign edited after
    its run (a marker offset, a row, its URDF) would otherwise be used with results it did not make,
    and give a quiet wrong number. The message names the campaign, both hashes and the files that
    differ. The campaign's result files that are there must also still have the SHA-256 the audit
    recorded: one edited, truncated or corrupted since (its time stamp kept) is named."""
    path = Path(results_dir) / layout.AUDIT
    if not path.is_file():
        raise InputError(
            "not written: `snakemake -j2` writes it when its run completes; the results are used only with "
            "the campaign whose content hash it records",
            file=str(path),
        )
    name = Path(campaign_folder).resolve().name
    recorded = read_json(path)
    key = f"campaigns/{name}"
    campaigns = recorded.get("campaigns") if isinstance(recorded, dict) else None
    record = campaigns.get(name) if isinstance(campaigns, dict) else None
    if not isinstance(record, dict) or not isinstance(record.get("files"), dict):
        raise InputError(
            f"the run that wrote these results did not include campaign {name}: run `snakemake -j2` on it",
            file=str(path),
            key=key,
        )
    now = campaign_digests(campaign_folder, repo_root)
    if audit.folder_digest(now) == record.get("content_sha256"):
        made_in = (recorded.get("config") or {}).get("results_dir")
        changed = _changed_results(Path(results_dir), record.get("results"), made_in)
        if changed:
            raise InputError(
                f"{listed(changed)}: changed since the run that made them recorded their SHA-256 (edited, truncated "
                "or corrupted): run `snakemake -j2` again (delete them first: their time stamps may not show it)",
                file=str(path),
                key=f"{key}/results",
            )
        return
    made = record["files"]
    differ = sorted(f for f in set(now) | set(made) if now.get(f) != made.get(f))
    raise InputError(
        f"the campaign {campaign_folder} has changed since these results were made from it: its content SHA-256 "
        f"is {audit.folder_digest(now)}, the results were made from {record.get('content_sha256')}"
        + (f" (files that differ: {listed(differ)})" if differ else "")
        + ": run `snakemake -j2` again, or give the campaign the results were made from",
        file=str(path),
        key=f"{key}/content_sha256",
    )


CAMPAIGN_REPORTS = ("certificate.md", "certificate.json")  # under results_dir/<campaign>
RUN_REPORTS = ("report.html", layout.AUDIT)  # under results_dir: every campaign's
# what the certificate reads of each sensor besides its acceptance test (the samplers' are optional)
SENSOR_RESULTS_READ = (layout.REGISTRATION, layout.LAPLACE, layout.LOOP_CLOSURE)


def stale_reports(results_dir: str | Path, sensors: Mapping[str, Iterable[str]]) -> list[Path]:
    """The reports in results_dir that no longer describe their results, after a run in which a job
    failed (its output removed, so the reports after it did not run): a campaign's certificate when
    a result of one of its sensors (`sensors`: {campaign: sensor names}) that it reads is missing or
    newer than it, and then the run's report and audit, which cover every campaign. Kept, they would
    show the numbers of a run whose results are gone."""
    results_dir = Path(results_dir)
    stale: list[Path] = []
    for campaign, names in sensors.items():
        reports = [results_dir / campaign / name for name in CAMPAIGN_REPORTS]
        reports = [r for r in reports if r.is_file()]
        if not reports:
            continue
        inputs = [
            results_dir / layout.SENSOR_FOLDER.format(campaign=campaign, sensor=sensor) / name
            for sensor in names
            for name in (*SENSOR_RESULTS_READ, layout.ACCEPTANCE)
        ]
        oldest = min(r.stat().st_mtime_ns for r in reports)
        if any(not i.is_file() or i.stat().st_mtime_ns > oldest for i in inputs):
            stale += reports
    if stale:
        stale += [results_dir / name for name in RUN_REPORTS if (results_dir / name).is_file()]
    return stale


# One writer per results folder. Snakemake locks the folder it runs in (`.snakemake/locks`), not the
# results folder: two checkouts given the same `results_dir` would both write it, and one would fail
# half-way on the other's files. The workflow takes this lock when it starts and gives it back when
# it ends (`Snakefile`: onstart, onsuccess, onerror). The lock is a file created exclusively (O_EXCL,
# atomic on a local file system) naming the host, the process and the folder it ran from; a lock whose
# process is gone on this host (a run that was killed) is taken over, and the log says so.
LOCK_FILE = ".remaster-writer.lock"


class ResultsLocked(InputError):
    """Another run is writing the results folder."""


def _lock_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # a process of another user holds that number: alive
        return True
    return True


def _lock_holder(lock: Path) -> dict:
    try:
        return json.loads(lock.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def _not_writable(folder: Path, exc: OSError) -> InputError:
    """The error for a results folder this run cannot write in (read-only, no permission, a full disk)."""
    return InputError(
        f"cannot write in the results folder: {exc.strerror or exc}: give a results_dir this user can write "
        "(results_dir in config.yaml, or --config results_dir=...)",
        file=str(folder),
    )


def take_lock(results: str | Path, pid: int | None = None) -> Path:
    """Take the lock of the results folder (created if missing) for process `pid` (default: this
    one). Raises ResultsLocked naming the folder, the host, the process and where it runs from
    when a live process holds it; takes over a lock whose process is gone on this host. A folder
    it cannot write in (read-only, no permission) is an InputError naming it, before any job."""
    folder = Path(results)
    lock = folder / LOCK_FILE
    me = {"host": socket.gethostname(), "pid": os.getpid() if pid is None else int(pid), "from": os.getcwd()}
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _not_writable(folder, exc) from None
    for _ in range(2):
        try:
            descriptor = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _lock_holder(lock)
            same_host = holder.get("host") == me["host"]
            if same_host and holder.get("pid") == me["pid"]:
                return lock  # this run already holds it
            if same_host and isinstance(holder.get("pid"), int) and not _lock_alive(holder["pid"]):
                logging.getLogger(__name__).warning(
                    "%s: taken over from process %s, which is gone (a run that was killed)", lock, holder["pid"]
                )
                lock.unlink(missing_ok=True)
                continue
            raise ResultsLocked(
                f"another run is writing this results folder (host {holder.get('host', '?')}, process "
                f"{holder.get('pid', '?')}, run from {holder.get('from', '?')}): wait for it to end, or give "
                f"another results_dir; if no run is writing it, delete {LOCK_FILE}",
                file=str(lock),
            ) from None
        except OSError as exc:  # a read-only folder or file system, a full disk: before any job, not a traceback
            raise _not_writable(folder, exc) from None
        with os.fdopen(descriptor, "w", encoding="utf-8") as out:
            json.dump(me, out)
        return lock
    raise ResultsLocked("could not take the lock: another run took it at the same time", file=str(lock))


def release_lock(results: str | Path, pid: int | None = None) -> None:
    """Give the lock back if process `pid` (default: this one) on this host holds it."""
    lock = Path(results) / LOCK_FILE
    holder = _lock_holder(lock)
    if holder.get("host") == socket.gethostname() and holder.get("pid") == (os.getpid() if pid is None else pid):
        lock.unlink(missing_ok=True)


# After a failed run, the campaigns whose results are complete still get their report and their
# comparison (`Snakefile`: onerror runs the workflow again on them); a campaign that failed is a row of
# the report naming what failed, never a number. A job's log (`files.log_to`) marks its failure with
# this record, followed by the traceback, whose last lines are the exception.
FAILED_RECORD = re.compile(r"^\S+ \S+ ERROR remaster: failed$")
LOG_RECORD = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d+ [A-Z]+ ")
NOT_RUN = "did not reach its results in this run, no job log of it naming a failure (a job killed, or not run after another failed): see its logs under logs/ and Snakemake's log"


def job_failure(log: str | Path) -> str | None:
    """The exception a failed job's log ends with (`files.log_to`), as "<type>: <message>" without
    the type's module; None when the log records no failure (or is not there)."""
    try:
        lines = Path(log).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    starts = [i for i, line in enumerate(lines) if FAILED_RECORD.match(line)]
    if not starts:
        return None
    exception: list[str] = []
    for line in lines[starts[-1] + 1 :]:
        if LOG_RECORD.match(line):
            break
        if line.startswith(("Traceback ", " ")) or not line.strip():
            exception = []  # a frame, or a chained exception's traceback: the exception comes after
            continue
        exception.append(line)
    if not exception:
        return None
    kind, colon, message = exception[0].partition(": ")
    first = f"{kind.rsplit('.', 1)[-1]}{colon}{message}"
    return "\n".join([first, *exception[1:]])


def failed_campaigns(
    results_dir: str | Path, results: Mapping[str, Iterable[str | Path]], since: float
) -> dict[str, str]:
    """{campaign: what failed} of the campaigns of a run whose results (`results`: {campaign: its
    result files}) are not all there: each job log under results_dir/logs/<campaign>/ written since
    `since` (a time.time()) that records a failure gives "<log>: <exception>" (`job_failure`), the
    log named from results_dir; a campaign without one did not run to its results (`NOT_RUN`)."""
    results_dir = Path(results_dir)
    failed = {}
    for campaign, paths in results.items():
        if all(Path(p).is_file() for p in paths):
            continue
        logs = sorted((results_dir / "logs" / campaign).rglob("*.log"))
        found = [(log, job_failure(log)) for log in logs if log.is_file() and log.stat().st_mtime >= since]
        found = [f"{log.relative_to(results_dir)}: {message}" for log, message in found if message]
        failed[campaign] = "\n".join(found) or NOT_RUN
    return failed
