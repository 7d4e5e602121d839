"""SI inside the library: the factors that turn its metres and radians into the mm and degrees of
tables and figures."""

from __future__ import annotations

import math

MM = 1e-3  # m per mm
DEG = math.pi / 180.0  # rad per degree
SECONDS_PER_HOUR = 3600.0  # s per hour (drift rates are shown per hour)


def shown(value: float, significant: int = 3) -> str:
    """A number with no uncertainty beside it, as tables and messages print it: `significant`
    digits, never fewer than its units ("1234", "6.31", "0.0102"); a whole number as an integer."""
    value = float(value)
    if not math.isfinite(value):
        return f"{value:g}"
    if value == round(value) and abs(value) < 1e15:
        return str(int(value))
    decimals = max(0, significant - 1 - math.floor(math.log10(abs(value))))
    return f"{value:.{decimals}f}"
