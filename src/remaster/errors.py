"""Errors that name what is wrong and where: the file, the key or column, and the rows."""

from __future__ import annotations

import reprlib
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

MAX_ROWS_SHOWN = 10
MAX_VALUE_SHOWN = 120  # characters of a value quoted in a message

# A value read from a file can be nested and huge (YAML aliases expand a 1 kB file into a structure
# of billions of elements): reprlib walks only the first levels and items of it, so quoting it costs
# no more than the text shown.
_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlong = 3, 80, 80, 40
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = _REPR.maxfrozenset = _REPR.maxdeque = 8


def listed(items: Iterable) -> str:
    """'3, 7, 9' or '0, 1, ... (250 in all)' for long lists: the first MAX_ROWS_SHOWN items as text."""
    items = [str(item) for item in items]
    shown = ", ".join(items[:MAX_ROWS_SHOWN])
    return shown + (f", ... ({len(items)} in all)" if len(items) > MAX_ROWS_SHOWN else "")


def format_rows(rows: Iterable[int], noun: str = "row") -> str:
    """'rows 3, 7, 9' or 'rows 0, 1, ... (250 in all)' for long lists ('line 4' with noun='line')."""
    rows = [int(r) for r in rows]
    return f"{noun} {listed(rows)}" if len(rows) == 1 else f"{noun}s {listed(rows)}"


def quoted(value: Any) -> str:
    """repr(value) for a message, shortened ('...') to at most MAX_VALUE_SHOWN characters whatever
    the size of the value."""
    text = _REPR.repr(value)
    return text if len(text) <= MAX_VALUE_SHOWN else text[: MAX_VALUE_SHOWN - 3] + "..."


class RemasterError(Exception):
    """Base class of every error remaster raises on purpose."""


class InputError(RemasterError, ValueError):
    """Bad input: the message names the file, the key or column, and the offending rows.

    Rows are 0-based positions in the table as stored.
    """

    def __init__(
        self, message: str, *, file: str | None = None, key: str | None = None, rows: Iterable[int] | None = None
    ):
        self.file = file
        self.key = key
        self.rows = None if rows is None else [int(r) for r in rows]
        self.reason = message
        where = ": ".join(str(part) for part in (file, key) if part)
        text = f"{where}: {message}" if where else message
        if self.rows:
            text += f" ({format_rows(self.rows)})"
        super().__init__(text)


class KinematicsError(InputError):
    """A robot model that cannot be used: missing frames, unsupported joints, a non-serial chain."""


def report_reader(content: Mapping, source: str, message: str):
    """get(*keys): the value at a path of nested keys of a stage's JSON report; InputError naming
    the file and the path when a key is missing."""

    def get(*keys):
        value = content
        for depth, key in enumerate(keys):
            if not isinstance(value, Mapping) or key not in value:
                raise InputError(message, file=source, key="/".join(keys[: depth + 1]))
            value = value[key]
        return value

    return get


def require_columns(
    table,
    required: Iterable[str],
    *,
    file: str | None,
    kind: str = "",
    of: str = "",
    note: str = "",
    listed: bool = False,
) -> None:
    """The one check that a table (anything with `.columns`) has every required column: else an
    InputError naming the file and the missing columns, "missing [kind ]column(s)[ of <of>]", then in
    parentheses the note and, when `listed`, the columns the table has ("got: ...")."""
    columns = list(table.columns)
    missing = [str(c) for c in required if c not in columns]
    if not missing:
        return
    details = [note] if note else []
    if listed:
        details.append(f"got: {', '.join(map(str, columns))}")
    message = f"missing {kind + ' ' if kind else ''}column(s){' of ' + of if of else ''}"
    raise InputError(message + (f" ({'; '.join(details)})" if details else ""), file=file, key=", ".join(missing))


def refuse_millimetres(
    values, limit: float, what: str, *, file: str | None, key: str, error: type[InputError] = InputError
) -> None:
    """The one check that lengths given in metres are plausible: an InputError (or `error`) naming
    the file and the key when a magnitude reaches `limit` (m), "looks like mm": millimetres written
    for metres are the likely slip. `what` names the bound ("the bound of a plausible marker offset
    from the flange"). A 2-D table of values (rows, columns) names its offending rows."""
    values = np.abs(np.asarray(values, dtype=float))
    beyond = values >= limit
    if not beyond.any():
        return
    rows = np.flatnonzero(beyond.any(axis=1)) if values.ndim == 2 else None
    raise error(
        f"{values[beyond].max():g} m is not below {limit:g} m, {what}: looks like mm written for m (write metres)",
        file=file,
        key=key,
        rows=rows,
    )


ROTATION_TOLERANCE = 1e-4  # rad: a rotation vector's norm may pass pi by this much (pi written 3.1416)


def refuse_degrees(
    vectors,
    *,
    file: str | None,
    key: str,
    rows: Iterable[int] | None = None,
    row_name: str = "row",
    advice: str = "write radians",
    error: type[InputError] = InputError,
) -> None:
    """The one check that rotation vectors given in rad are plausible: an InputError (or `error`)
    naming the file and the key when a norm passes pi rad (180 deg, the longest rotation) by more
    than ROTATION_TOLERANCE, "looks like degrees" (with the value in rad) where degrees are the
    likely slip, "not a rotation vector" beyond a turn even as degrees. `vectors` (3,) or (n, 3),
    finite; a table of them names its offending rows (`rows`: their labels, default 0..n-1, called
    `row_name` in the message, e.g. "line"); `advice` ends the message where degrees are likely."""
    vectors = np.asarray(vectors, dtype=float)
    table = np.atleast_2d(vectors)
    scale = np.max(np.abs(table), axis=1, initial=0.0)  # the norm of [1e300, 1e300, 0] without overflow
    with np.errstate(invalid="ignore", divide="ignore"):
        norms = scale * np.linalg.norm(table / np.where(scale > 0, scale, 1.0)[:, None], axis=1)
    beyond = np.flatnonzero(~(norms <= np.pi + ROTATION_TOLERANCE))
    if beyond.size == 0:
        return
    worst = float(norms[beyond].max())
    as_radians = np.deg2rad(worst)
    unit = (
        f"looks like degrees: {worst:.6g} deg = {as_radians:.4g} rad ({advice})"
        if as_radians <= 2 * np.pi + ROTATION_TOLERANCE
        else f"not a rotation vector in rad, nor in degrees ({worst:.6g} deg is beyond a turn)"
    )
    message = f"a rotation vector of norm {worst:.6g} rad is beyond pi rad (180 deg, the longest rotation): {unit}"
    if vectors.ndim != 2:
        raise error(message, file=file, key=key)
    labels = (np.arange(len(norms)) if rows is None else np.asarray(list(rows)))[beyond]
    if row_name == "row":
        raise error(message, file=file, key=key, rows=labels)
    raise error(f"{message} ({format_rows(labels, row_name)})", file=file, key=key)
