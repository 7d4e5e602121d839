"""What a calibration is used for: `predict` and `compensate` (what `remaster predict` and
`remaster compensate` run, on a `Calibration` instead of a results folder) and `compare` (the
workflow's comparisons across campaigns and sensors, on calibrations).

SI in (m, rad); the tables give positions in m and errors and bounds in mm.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from .. import configuration, identity
from ..calibration import compensation, prediction
from ..comparing import comparison, transfer
from .calibration import Calibration


def _commands(calibration: Calibration, q) -> np.ndarray:
    """Joint commands (n, N) rad from an array or a table with columns q1..qN, checked as
    `remaster predict` checks its file (finite, within the joint limits)."""
    chain = calibration.campaign.chain
    if not isinstance(q, pd.DataFrame):
        q = np.atleast_2d(np.asarray(q, dtype=float))
        q = pd.DataFrame(q, columns=[f"q{j + 1}" for j in range(q.shape[1])])
    return compensation.joint_commands(q, chain, "commands")


def predict(
    calibration: Calibration,
    q,
    *,
    model: str = "loop",
    frame: str = "robot",
    tcp=None,
    draws: int = 2000,
    seed: int = 0,
) -> pd.DataFrame:
    """Where the calibrated robot puts its tool at joint commands q ((n, N) rad, or a table with
    q1..qN), in the robot's base frame ('robot') or the campaign's sensor frame ('sensor'): one row
    per command with x, y, z (m), nominal_x..z (m), correction_mm, bound95_mm (the posterior's 95 %
    bound, `draws` draws from `seed`: an int, or a numpy Generator to draw from) and
    bound95_with_noise_mm (`compensation.predict`). model:
    'loop' (the loop-closed model) or 'paper' (zero-offsets); tcp (3,) m in the flange frame, or
    None for the sensor's marker."""
    robot = calibration.robot(model, tcp)
    return compensation.predict(robot, _commands(calibration, q), frame, draws, np.random.default_rng(seed))


def compensate(
    calibration: Calibration,
    targets=None,
    *,
    commands=None,
    model: str = "loop",
    frame: str = "robot",
    tcp=None,
    draws: int = 2000,
    seed: int = 0,
) -> pd.DataFrame:
    """The joint commands that put the calibrated robot's tool at `targets` ((n, 3) m in `frame`;
    inverse kinematics from the campaign's nearest measured configuration) or, given nominal
    `commands` ((n, N) rad) instead, where the nominal model puts it (`compensation.compensate`):
    one row per target with status ('reached' or why not), q1..qN (rad), nominal_q1..qN,
    largest_change_deg, error_mm and bound95_mm. model, frame, tcp, draws, seed: as `predict`."""
    if (targets is None) == (commands is None):
        raise ValueError("give targets or commands, not both")
    robot = calibration.robot(model, tcp)
    return compensation.compensate(
        robot,
        frame,
        draws,
        np.random.default_rng(seed),
        commands=None if commands is None else _commands(calibration, commands),
        targets=targets,
        candidates=calibration.campaign.sensors[calibration.sensor].q("optimization"),
    )


def compare(*calibrations: Calibration, settings: Mapping[str, Any] | None = None) -> dict[str, pd.DataFrame]:
    """The workflow's comparisons of these calibrations (two or more, of one robot or several):
    by their parameters (`comparison.TABLES`: zero-offsets over time, drift between consecutive
    campaigns of one robot and sensor kind, the agreement of one campaign's sensors, and the same of
    the loop-closure parameters; z-scores flagged beyond settings' comparison/significance) and by
    what they predict (`transfer.prediction_stage`: each calibration on the others' data, and the
    drift and agreement of predicted positions at the robot's random configurations, mm). {table
    name: table}; `settings` as `calibrate`'s (its comparison section and seed). The zero-offset
    model's tables compare nothing where its summary has no std: `calibrate` gives its Laplace mode
    alone (no paper sampler), so its drift and agreement say 'not comparable'; the loop-closed
    model's carry its MCMC refit's std."""
    config = configuration.settings(settings)
    section = config["comparison"]
    keyed = {(c.campaign.name, c.sensor): c for c in calibrations}
    entries = [
        comparison.Entry(
            c.campaign.name,
            c.campaign.date,
            c.sensor,
            c.summary,
            identity.robot_identity(c.campaign),
            c.campaign.sensors[c.sensor].kind,
            c.loop.report.parameters,
            c.loop.report.closed,
        )
        for c in keyed.values()
    ]
    predicted = transfer.prediction_stage(
        {c.campaign.name: c.campaign for c in keyed.values()},
        {key: c.results()["summary"] for key, c in keyed.items()},
        {key: c.laplace for key, c in keyed.items()},
        {key: c.loop.report for key, c in keyed.items()},
        {},
        {key: c.loop.samples for key, c in keyed.items() if c.loop.samples is not None},
        prediction.Propagation(section["draw_pairs"], section["random_configurations"], config["seed"]),
    )
    return {**comparison.tables_of(entries, section["significance"]), **predicted}
