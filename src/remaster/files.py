"""Reading and writing plain files: YAML, JSON, CSV, Parquet, text, figures, and a job's log.

Every writer creates the file's folder and is deterministic (same data, same bytes); every reader
raises InputError naming the file when it is missing or malformed. What the files mean (campaign
folders, a stage's report) is for the modules that call these.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import errno
import json
import logging
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from .errors import InputError


def plain(value: Any) -> Any:
    """Nested mappings/sequences of NumPy or Python values -> plain dicts, lists, floats, ints, str
    (non-finite floats -> None, paths -> str)."""
    if isinstance(value, Mapping):
        return {str(k) if isinstance(k, Path) else k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


# --------------------------------------------------------------------------- YAML and JSON


class _Refused(yaml.YAMLError):
    """A YAML document remaster refuses although YAML allows it; the message says why, `key` where."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.key = key


class _PlainLoader(yaml.SafeLoader):
    """yaml.SafeLoader without aliases: `*name` repeats what `&name` marks, and nested repetitions
    expand a 1 kB file into billions of values ("billion laughs") that exhaust time and memory as
    soon as anything walks them. remaster's YAML files need none."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise _Refused(
                f"line {event.start_mark.line + 1}: YAML alias *{event.anchor} refused: remaster reads plain YAML "
                "without anchors and aliases (their expansion can exhaust memory); write the value out"
            )
        return super().compose_node(parent, index)


def _duplicate_keys(node: yaml.Node, path: tuple[str, ...] = ()) -> None:
    """_Refused, naming the key's path and lines, when a mapping of the document gives a key twice:
    YAML loaders keep the last one silently, so a value written first would be quietly ignored."""
    if isinstance(node, yaml.MappingNode):
        first: dict[tuple[str, str], int] = {}
        for key_node, value_node in node.value:
            key = str(key_node.value) if isinstance(key_node, yaml.ScalarNode) else "?"
            line = key_node.start_mark.line + 1
            if isinstance(key_node, yaml.ScalarNode) and (key_node.tag, key) in first:
                raise _Refused(
                    f"line {line}: duplicate key (first on line {first[key_node.tag, key]}): YAML would keep only "
                    "the last value, so remaster refuses the file",
                    key="/".join((*path, key)),
                )
            first.setdefault((key_node.tag, key), line)
            _duplicate_keys(value_node, (*path, key))
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            _duplicate_keys(item, (*path, str(index)))


def load_yaml(text: str, source: str) -> Any:
    """The content of YAML `text` with plain YAML's types only (a yaml.SafeLoader), refusing
    aliases and duplicate keys; InputError naming `source` (and the key and line) otherwise."""
    loader = _PlainLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _duplicate_keys(node)
        return loader.construct_document(node)
    except _Refused as exc:
        raise InputError(str(exc), file=source, key=exc.key) from None
    except RecursionError:  # the parser recurses once per level: '[[[[...' a hundred thousand deep
        raise InputError("YAML nested too deep to read: remaster's files need a few levels", file=source) from None
    except yaml.YAMLError as exc:
        tag = re.search(r"constructor for the tag '([^']*)'", str(getattr(exc, "problem", "")))
        if tag:  # e.g. !!python/object/apply: safe_load has no constructor for it
            mark = getattr(exc, "problem_mark", None)
            line = f"line {mark.line + 1}: " if mark is not None else ""
            raise InputError(
                f"{line}YAML tag {tag.group(1)!r} refused: remaster reads plain YAML (yaml.safe_load) "
                f"and never builds objects from tags; nothing was executed",
                file=source,
            ) from None
        raise InputError(f"not valid YAML: {exc}", file=source) from None
    finally:
        loader.dispose()


def read_text(path: str | Path, encoding: str = "utf-8") -> str:
    """The text of a file; InputError naming it when it is missing, a directory, not text in
    `encoding` (the line and byte that are not), or unreadable (permissions, a symlink loop): the
    operating system's exceptions would otherwise end a run in a traceback naming no input."""
    path = Path(path)
    try:
        return path.read_text(encoding=encoding)
    except FileNotFoundError:
        raise InputError("file not found", file=str(path)) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a file", file=str(path)) from None
    except UnicodeDecodeError as exc:
        line = exc.object[: exc.start].count(b"\n") + 1
        raise InputError(
            f"line {line}: not UTF-8 text: byte 0x{exc.object[exc.start]:02x} ({exc.reason}): save the file as UTF-8",
            file=str(path),
        ) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", file=str(path)) from None


def read_yaml(path: str | Path) -> Any:
    """Content of a YAML file (`load_yaml`); InputError naming the file if missing or malformed,
    if it holds a tag plain YAML has no constructor for (e.g. !!python/object/apply), an alias or a
    duplicate key."""
    return load_yaml(read_text(path), str(path))


def write_yaml(path: str | Path, data: Any) -> Path:
    """Write `data` as block YAML, keys in the given order, leaf lists inline; same data, same bytes."""
    text = yaml.safe_dump(plain(data), sort_keys=False, allow_unicode=True, default_flow_style=None, width=100)
    return write_text(path, text)


def read_json(path: str | Path) -> Any:
    """Content of a JSON file; InputError naming the file if missing or malformed."""
    text = read_text(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc}", file=str(path)) from None


def write_json(path: str | Path, data: Any) -> Path:
    """Write `data` as indented JSON with sorted keys and a final newline; same data, same bytes.

    NumPy values become plain numbers/lists, dates ISO strings; NaN and infinities become null,
    so the file is strict JSON that any reader accepts.
    """
    path = Path(path)
    return write_text(path, json_text(data, str(path)) + "\n")


def json_text(data: Any, label: str = "JSON") -> str:
    """The JSON text `write_json` writes of `data` (without its final newline); `label` names
    where it goes in the error for a value JSON cannot hold."""

    def fallback(value: Any) -> Any:
        if isinstance(value, (dt.date, dt.datetime)):
            return value.isoformat()
        raise TypeError(f"cannot write {type(value).__name__} to JSON ({label})")

    return json.dumps(plain(data), sort_keys=True, indent=2, ensure_ascii=False, default=fallback, allow_nan=False)


def number_or_nan(value) -> float:
    """A number as `write_json` wrote it, back as a float: NaN for null (a NaN or infinity
    written) and for anything that is not a number (a missing value is a blank, never a crash)."""
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


@contextlib.contextmanager
def _written(path: Path):
    """A file beside `path` to write to (hidden, same suffix: writers infer the format from it),
    moved into place once written, its folder created first. A write that fails (a directory in
    the file's place, a full disk, no permission) leaves neither a partial file nor a changed
    earlier one, and is an InputError naming `path` rather than an OSError's traceback."""
    partial = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        yield partial
        partial.replace(path)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc}", file=str(path)) from None
    finally:
        with contextlib.suppress(OSError):
            partial.unlink(missing_ok=True)


def write_text(path: str | Path, text: str) -> Path:
    """Write text (UTF-8, newlines as given) to `path`, creating its folder."""
    path = Path(path)
    with _written(path) as partial:
        partial.write_text(text, encoding="utf-8", newline="\n")
    return path


# --------------------------------------------------------------------------- tables


def read_csv(path: str | Path) -> pd.DataFrame:
    """A CSV table; InputError naming the file if it is missing or unreadable."""
    path = Path(path)
    try:
        return pd.read_csv(path)
    except FileNotFoundError:
        raise InputError("file not found", file=str(path)) from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=str(path)) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a file", file=str(path)) from None
    except OSError as exc:  # permissions, a symlink loop
        raise InputError(f"cannot read: {exc.strerror or exc}", file=str(path)) from None


def write_csv(path: str | Path, table: pd.DataFrame) -> Path:
    """Write a table as CSV without its index, floats at full precision; same data, same bytes."""
    path = Path(path)
    with _written(path) as partial:
        table.to_csv(partial, index=False, float_format="%.17g", lineterminator="\n")
    return path


def missing_reason(path: str | Path) -> str:
    """Why a file that should be there is not: "file not found", or the symbolic link that stands
    in its place and leads nowhere (its target missing, or a loop of links)."""
    path = Path(path)
    if not path.is_symlink():
        return "file not found"
    target = os.readlink(path)
    try:
        path.stat()
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return f"a symbolic link (to {target!r}) that loops back on itself: no file at its end"
    return (
        f"a symbolic link to {target!r}, which does not exist (a dangling link: copy the file, or link to where it is)"
    )


def read_parquet(path: str | Path) -> pd.DataFrame:
    """A Parquet table; InputError naming the file if it is missing or cannot be read."""
    path = Path(path)
    if path.is_dir():  # pd.read_parquet would read a folder as a partitioned data set
        raise InputError("is a directory, not a file", file=str(path))
    if not path.is_file():
        raise InputError(missing_reason(path), file=str(path))
    try:
        return pd.read_parquet(path)
    except (OSError, pa.ArrowException, ValueError) as exc:
        raise InputError(f"cannot read Parquet: {exc}", file=str(path)) from None


def write_parquet(path: str | Path, table: pd.DataFrame) -> Path:
    """Write a table as Parquet (pyarrow) without its index; same data, same bytes."""
    path = Path(path)
    with _written(path) as partial:
        pq.write_table(pa.Table.from_pandas(table, preserve_index=False), partial)
    return path


# --------------------------------------------------------------------------- figures and logs


def write_figure(stem: str | Path, figure) -> list[Path]:
    """Save a matplotlib figure as <stem>.png and <stem>.pdf, reproducibly (no timestamps), and close it."""
    import matplotlib.pyplot as plt  # here: a job that writes no figure does not load matplotlib

    stem = Path(stem)
    paths = [stem.with_suffix(".png"), stem.with_suffix(".pdf")]
    # tight_layout() leaves a placeholder layout engine, for which every savefig lays the figure out
    # again in a draw of its own before drawing it: the figures are laid out already, and that draw
    # (most of the text measuring) would double each save's time for the same bytes
    figure.set_layout_engine(None)
    try:
        with _written(paths[0]) as partial:
            figure.savefig(partial, dpi=120, metadata={"Software": None})
        with _written(paths[1]) as partial:
            figure.savefig(partial, metadata={"Creator": None, "Producer": None, "CreationDate": None})
    finally:
        plt.close(figure)
    return paths


@contextlib.contextmanager
def log_to(path: str | Path, level: int = logging.INFO):
    """Send remaster's log records to `path` for the duration; an exception is logged with its
    traceback before it propagates, so a failed workflow job's log says why. A log that cannot be
    written (a read-only folder) is an InputError naming it."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handler = logging.FileHandler(path, mode="w", encoding="utf-8")
    except OSError as exc:  # a read-only results folder: named, not a traceback
        raise InputError(f"cannot write the log: {exc.strerror or exc}", file=str(path)) from None
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
