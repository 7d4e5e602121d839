"""SI inside the library: the factors that turn its metres and radians into the mm and degrees of
tables and figures."""

from __future__ import annotations

import math

MM = 1e-3  # m per mm
DEG = math.pi / 180.0  # rad per degree
