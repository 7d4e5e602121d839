"""remaster's Python interface: one sensor of a campaign calibrated in-process, and what a
calibration is used for.

    from remaster import api

    calibration = api.calibrate("data/raw/jacobi-ur5-gts3800", "laser_tracker", api.settings())
    calibration.verdict, calibration.effects      # the acceptance test's verdict, the loop's effects
    api.predict(calibration, q)                   # where the tool is at commands q (n, N) rad
    api.compensate(calibration, targets)          # the commands that put it at targets (n, 3) m
    api.compare(calibration, other)               # the workflow's comparison tables

`settings` is the configuration with the schema's defaults filled in (the schema the workflow
validates config.yaml against: one place for the defaults); `calibrate` runs the workflow's stages
(`calibration`); `predict`, `compensate` and `compare` are what `remaster predict`, `remaster
compensate` and the workflow's comparisons run (`use`); `truth` holds a calibration of a simulated
campaign to the truth it was simulated from; `stages` holds the stage functions the workflow's
scripts call, one each. SI units (m, rad) in, mm in the tables' errors.

Nothing is imported until a name is used (`from remaster import api` stays light, as each workflow
job starts a fresh Python): each name is imported from its module on first use, then kept here.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # for type checkers and editors; at run time the names come from __getattr__
    from ..configuration import settings
    from .calibration import Calibration, calibrate
    from .use import compare, compensate, predict

# {name: the module (relative to this package) that defines it}
_NAMES = {
    "settings": "..configuration",
    "Calibration": ".calibration",
    "calibrate": ".calibration",
    "compare": ".use",
    "compensate": ".use",
    "predict": ".use",
}
# the sub-modules, reachable as attributes (`api.truth`, `api.stages`) as an eager package's are
_SUBMODULES = ("calibration", "stages", "truth", "use")

__all__ = ["Calibration", "calibrate", "compare", "compensate", "predict", "settings"]


def __getattr__(name: str):
    if name in _NAMES:
        value = getattr(importlib.import_module(_NAMES[name], __name__), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__, *_SUBMODULES})
