"""One writer per results folder.

Snakemake locks the folder it runs in (`.snakemake/locks`), not the results folder: two checkouts
given the same `results_dir` would both write it, and one would fail half-way on the other's
files. The workflow takes this lock when it starts and gives it back when it ends
(`Snakefile`: onstart, onsuccess, onerror). The lock is a file created exclusively (O_EXCL, atomic
on a local file system) that names the host, the process and the folder it ran from; a lock whose
process is gone on this host (a run that was killed) is taken over, and the log says so.
"""

from __future__ import annotations

import json
import logging
import os
import socket
from pathlib import Path

from .errors import InputError

LOCK_FILE = ".remaster-writer.lock"
log = logging.getLogger(__name__)


class ResultsLocked(InputError):
    """Another run is writing the results folder."""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # a process of another user holds that number: alive
        return True
    return True


def _holder(lock: Path) -> dict:
    try:
        return json.loads(lock.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def take(results: str | Path, pid: int | None = None) -> Path:
    """Take the lock of the results folder (created if missing) for process `pid` (default: this
    one). Raises ResultsLocked naming the folder, the host, the process and where it runs from
    when a live process holds it; takes over a lock whose process is gone on this host."""
    folder = Path(results)
    folder.mkdir(parents=True, exist_ok=True)
    lock = folder / LOCK_FILE
    me = {"host": socket.gethostname(), "pid": os.getpid() if pid is None else int(pid), "from": os.getcwd()}
    for _ in range(2):
        try:
            descriptor = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _holder(lock)
            same_host = holder.get("host") == me["host"]
            if same_host and holder.get("pid") == me["pid"]:
                return lock  # this run already holds it
            if same_host and isinstance(holder.get("pid"), int) and not _alive(holder["pid"]):
                log.warning(
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
        with os.fdopen(descriptor, "w", encoding="utf-8") as out:
            json.dump(me, out)
        return lock
    raise ResultsLocked("could not take the lock: another run took it at the same time", file=str(lock))


def release(results: str | Path, pid: int | None = None) -> None:
    """Give the lock back if process `pid` (default: this one) on this host holds it."""
    lock = Path(results) / LOCK_FILE
    holder = _holder(lock)
    if holder.get("host") == socket.gethostname() and holder.get("pid") == (os.getpid() if pid is None else pid):
        lock.unlink(missing_ok=True)
