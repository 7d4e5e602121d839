"""Transfer between campaigns of one robot: what a calibration is worth on another campaign.

Campaign X's calibration (`prediction.Calibration`: nominal, paper or loop) is applied to campaign
Y's readings of the same sensor (same sensor name, campaigns of one `identity.robot_identity`):

1. robot-frame marker positions from X's kinematics at Y's readings (Y's nominal marker plus X's
   marker offset; a compliance acts through the gravity torques at Y's readings);
2. Y's registration refitted on Y's OPTIMIZATION rows with X's kinematics frozen (Kabsch, 6 DOF:
   Y's sensor stood elsewhere);
3. the post-registration errors |measured - T p| on Y's VALIDATION rows: rmse_mm, mean_mm, p95_mm.

X = Y is the campaign's ordinary validation with a least-squares registration. Rows whose marker
was not seen (NaN) and Y's flagged gross errors are left out of both steps; `count` counts the
validation rows used. The registration and sensor scale (Y's sensor set-up) and the drift (X's
clock or temperature) are not transferred: they are refitted or do not apply.

SI inside; the table in mm.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pandas as pd

from .. import spatial
from ..calibration.prediction import MODELS, Calibrated, Calibration, Propagation, calibrated_entries
from ..errors import InputError
from ..inference import metrics
from ..robot import registration

TRANSFER_COLUMNS = [
    "robot",
    "sensor",
    "model",
    "calibrated_on",
    "evaluated_on",
    "count",
    "rmse_mm",
    "mean_mm",
    "p95_mm",
]
MIN_REGISTRATION_POINTS = 3


def transfer_errors(calibration: Calibration, target: Calibrated) -> np.ndarray:
    """Post-registration errors (n,) m of `calibration` on the target's validation rows used (seen,
    not flagged), with the target's registration refitted (Kabsch) on its optimization rows used.
    Empty when the target has fewer than MIN_REGISTRATION_POINTS optimization rows or no
    validation row."""
    sensor, excluded = target.sensor, np.asarray(target.excluded, dtype=int)
    rows = {s: np.setdiff1d(sensor.measured_rows(s), excluded) for s in ("optimization", "validation")}
    if len(rows["optimization"]) < MIN_REGISTRATION_POINTS or len(rows["validation"]) == 0:
        return np.empty(0)
    joints, xyz = list(sensor.joint_columns), ["x", "y", "z"]
    q = {s: sensor.table.loc[r, joints].to_numpy(float) for s, r in rows.items()}
    measured = {s: sensor.table.loc[r, xyz].to_numpy(float) for s, r in rows.items()}
    # one predictor over both sets: one gravity-torque computation, one kernel set-up
    everything = calibration.predictor(target.chain, np.vstack([q["optimization"], q["validation"]]), sensor.marker)
    points = everything.points(calibration.values)
    n_opt = len(q["optimization"])
    sensor_from_robot = registration.kabsch(points[:n_opt], measured["optimization"])
    predicted = spatial.transform_points(sensor_from_robot, points[n_opt:])
    return np.linalg.norm(measured["validation"] - predicted, axis=1)


SUMMARY = ("rmse", "mean", "p95")  # of the validation errors (`metrics.error_summary`)


def transfer_table(entries: Iterable[Calibrated]) -> pd.DataFrame:
    """Every calibration of every campaign applied to every campaign of the same robot and sensor
    name (itself included), per model (nominal, paper, loop) the calibrating entry has.

    Columns TRANSFER_COLUMNS: robot, sensor, model, calibrated_on (X), evaluated_on (Y), count
    (Y's validation rows used), rmse_mm, mean_mm, p95_mm. Sorted by robot, sensor, model (nominal,
    paper, loop), X and Y in date order (then name).
    """
    entries = sorted(entries, key=lambda e: (e.robot, e.sensor.name, e.date, e.campaign))
    seen = set()
    for e in entries:
        if (e.campaign, e.sensor.name) in seen:
            raise InputError("given twice", file=f"{e.campaign}/{e.sensor.name}")
        seen.add((e.campaign, e.sensor.name))
    rows = []
    for model in MODELS:
        for source in entries:
            if model not in source.models:
                continue
            for target in entries:
                if (target.robot, target.sensor.name) != (source.robot, source.sensor.name):
                    continue
                rows.append(
                    {
                        "robot": source.robot,
                        "sensor": source.sensor.name,
                        "model": model,
                        "calibrated_on": source.campaign,
                        "evaluated_on": target.campaign,
                        **metrics.in_mm(metrics.error_summary(transfer_errors(source.models[model], target), SUMMARY)),
                    }
                )
    if not rows:
        return pd.DataFrame(columns=TRANSFER_COLUMNS)
    table = pd.DataFrame(rows, columns=TRANSFER_COLUMNS)
    table["model_order"] = table["model"].map({m: i for i, m in enumerate(MODELS)})
    return table.sort_values(["robot", "sensor", "model_order"], kind="stable")[TRANSFER_COLUMNS].reset_index(drop=True)


def transfer_stage(campaigns, summaries, laplaces, loops=None) -> pd.DataFrame:
    """`transfer_table` of the campaigns' calibrations (arguments as `prediction.calibrated_entries`)."""
    return transfer_table(calibrated_entries(campaigns, summaries, laplaces, loops))


def prediction_stage(
    campaigns,
    summaries,
    laplaces,
    loops,
    paper_samples,
    loop_samples,
    propagation: Propagation,
) -> dict[str, pd.DataFrame]:
    """The comparisons by prediction (arguments as `prediction.calibrated_entries`): the transfer
    table, then every table of `predictions.PREDICTION_TABLES` at the propagation's random
    configurations per robot (from its seed), with its draws as posterior draw pairs."""
    from .predictions import PREDICTION_TABLES

    out = {"transfer": transfer_stage(campaigns, summaries, laplaces, loops)}
    # one set of calibrated entries (with their posterior samples) for every prediction table
    entries = calibrated_entries(campaigns, summaries, laplaces, loops, paper_samples, loop_samples)
    for name, table in PREDICTION_TABLES.items():
        out[name] = table(entries, propagation.random_configurations, propagation.seed, propagation.draws)
    return out
