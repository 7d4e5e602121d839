"""Transfer between campaigns of one robot: what a calibration is worth on another campaign.

Campaign X's calibration (`prediction.Calibration`: nominal, paper or loop) is applied to campaign
Y's readings of the same sensor (same sensor name, campaigns of one `identity.robot_identity`):

1. flange poses from X's kinematics at Y's readings (a compliance acts through the gravity torques
   at Y's readings);
2. Y's set-up refitted on Y's OPTIMIZATION rows with X's kinematics frozen: the registration (6 DOF:
   Y's sensor stood elsewhere) and the marker on the flange (3 DOF: a marker is remounted between
   campaigns), `registration.kabsch_with_marker`, the marker's prior centred on Y's nominal marker
   plus X's marker offset with the marker's prior std (`Calibrated.marker_std`), against the larger
   of Y's stated noise and the scatter the fit leaves (`refitted_set_up`), so what Y's tool
   orientations barely turn keeps X's marker;
3. the post-registration errors |measured - T F m| on Y's VALIDATION rows: rmse_mm, mean_mm, p95_mm.

X = Y is the campaign's ordinary validation with the registration and the marker refitted. Rows
whose marker was not seen (NaN) and Y's flagged gross errors are left out of both steps; `count`
counts the validation rows used. The registration, sensor scale and marker (Y's sensor set-up, the
sensor's side of `loop.sides`) and the drift (X's clock or temperature) are not transferred: they are
refitted or do not apply.

SI inside; the table in mm.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pandas as pd

from .. import spatial
from ..calibration.prediction import MODELS, Calibrated, Calibration, Propagation, calibrated_entries
from ..errors import InputError
from ..inference import gauge, metrics
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
MIN_NOISE = 1e-9  # m: a noiseless simulation still weighs the marker's prior by a finite ratio
SCATTER_ROUNDS = 10  # at most: the scatter settles within 1 % in two or three


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
    flange = everything.flange_poses(calibration.values)
    carried = np.asarray(sensor.marker, dtype=float) + [calibration.values.get(n, 0.0) for n in gauge.MARKER]
    n_opt = len(q["optimization"])
    sensor_from_robot, marker = refitted_set_up(
        flange[:n_opt], carried, measured["optimization"], sensor.noise, target.marker_std
    )
    predicted = spatial.transform_points(sensor_from_robot, spatial.transform_points(flange[n_opt:], marker))
    return np.linalg.norm(measured["validation"] - predicted, axis=1)


def refitted_set_up(flange, carried, measured, stated_noise, marker_std) -> tuple[np.ndarray, np.ndarray]:
    """The target's registration T_NR (4, 4) and marker (3,) m refitted (`registration.kabsch_with_marker`)
    at flange poses (n, 4, 4) to its points (n, 3), the marker's prior centred on `carried`. The scatter
    it is fitted against is the larger of the stated noise (m per axis, or None) and the residual's RMS
    per axis, re-estimated until it settles: another campaign's kinematics leave a model error that a
    weakly turned marker direction would otherwise take up, and a marker that was all that was wrong
    leaves the noise alone."""
    floor = max(stated_noise or 0.0, MIN_NOISE)
    marker, noise = np.asarray(carried, dtype=float), None
    for _ in range(SCATTER_ROUNDS):
        points = spatial.transform_points(flange, marker)
        residual = measured - spatial.transform_points(registration.kabsch(points, measured), points)
        scatter = max(floor, float(np.sqrt(np.mean(residual**2))))
        if noise is not None and abs(scatter - noise) <= 0.01 * noise:
            break
        noise = scatter
        sensor_from_robot, marker = registration.kabsch_with_marker(flange, carried, measured, noise, marker_std)
    return sensor_from_robot, marker


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
