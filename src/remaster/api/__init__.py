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
campaign to the truth it was simulated from. SI units (m, rad) in, mm in the tables' errors.
"""

from ..configuration import settings
from .calibration import Calibration, calibrate
from .use import compare, compensate, predict

__all__ = ["Calibration", "calibrate", "compare", "compensate", "predict", "settings"]
