"""SI inside the library: the factors that turn its metres and radians into the mm and degrees of
tables and figures."""

from __future__ import annotations

import math

MM = 1e-3  # m per mm
DEG = math.pi / 180.0  # rad per degree
SECONDS_PER_HOUR = 3600.0  # s per hour (drift rates are shown per hour)


# Below this magnitude a number prints in scientific form: "6.59e-07", not "0.000000659" (the limit
# of Python's "g" format, so "0.000123" still prints as a decimal).
TINY = 1e-4


def shown(value: float, significant: int = 3) -> str:
    """A number with no uncertainty beside it, as tables and messages print it: `significant`
    digits, never fewer than its units ("1234", "6.31", "0.0102"); a whole number as an integer;
    a tiny one (|value| < TINY) in scientific form ("-6.59e-07")."""
    value = float(value)
    if not math.isfinite(value):
        return f"{value:g}"
    if value == round(value) and abs(value) < 1e15:
        return str(int(value))
    if abs(value) < TINY:
        return f"{value:.{max(0, significant - 1)}e}"
    decimals = max(0, significant - 1 - math.floor(math.log10(abs(value))))
    return f"{value:.{decimals}f}"


def shown_to(value: float, decimals: int) -> str:
    """A number rounded to `decimals` decimals (the decimal of its uncertainty), as tables print it:
    "-0.1894"; a tiny one (0 < |value as rounded| < TINY) in scientific form ending at the same
    decimal ("-6.59e-07" for decimals 9)."""
    value = float(value)
    rounded = round(value, decimals) if math.isfinite(value) else value
    if not (math.isfinite(rounded) and 0 < abs(rounded) < TINY):
        return f"{value:.{decimals}f}"
    return f"{rounded:.{max(0, decimals + math.floor(math.log10(abs(rounded))))}e}"
