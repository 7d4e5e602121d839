"""Steps 1 and 2 of the loop closure made without exactly the rows their own final model flags as
gross errors (`select_screened`): select, screen every optimization row with the final model
(`remaster.loop.gross`), select again without the rows it finds until they are the ones it was
fitted without; then the validation set screened with the final model. Also the optimization rows
the loop fits of a set larger than it fits (`fitted_rows`), and the screen's section of
loop_closure.json and its warnings (`gross_report`, `gross_warnings`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .. import noise
from ..campaigns.campaign import SETS, SensorData
from ..inference import gross_errors
from ..inference.readings import Readings, readings
from ..robot.kinematics import KinematicChain
from . import gross, noise_floor
from .selection import Selection, select
from .settings import LoopSettings


@dataclass(frozen=True, eq=False)
class Screened:
    """Steps 1-2 made without exactly the rows their own final model flags as gross errors.
    selection: the selection; data, poses: {set: readings, pose labels} without the flagged rows;
    every, every_poses: the same with every measured row; flagged: {set: table rows flagged};
    screens: {set: `gross_errors.Screen`}; provisional: the prepare stage's rows; history: the screen's
    rounds (each: the rows fitted without, the rows found, the effects its selection added);
    settled: whether the rows found were the rows left out; frame_problem: why a tracker's
    noise model cannot be offered in the fit's frame (None when it can); fitted, fitted_poses: the
    optimization readings the loop fitted and their poses (`fitted_rows`: every kept row, or one
    pose in k of a set larger than the loop fits); thinning: `fitted_rows`' record."""

    selection: Selection
    data: dict[str, Readings]
    poses: dict[str, np.ndarray]
    fitted: Readings
    fitted_poses: np.ndarray
    thinning: dict
    every: dict[str, Readings]
    every_poses: dict[str, np.ndarray]
    flagged: dict[str, np.ndarray]
    screens: dict[str, gross_errors.Screen]
    provisional: np.ndarray
    history: list[dict]
    settled: bool
    frame_problem: str | None


def select_screened(
    chain: KinematicChain, sensor: SensorData, t_nr, base_held, settings: LoopSettings, exclude
) -> Screened:
    """Select on the optimization set without the rows `exclude` (the zero-offset model's gross-error
    screen), screen every optimization row with the final model (`remaster.loop.gross`) and select
    again without the rows it finds, until they are the ones it was fitted without (bounded, a
    cycle stops it); then screen the validation set with the final model."""
    every = {s: readings(chain, sensor, s, settings.model) for s in SETS}
    every_poses = {s: sensor.table.loc[every[s].rows, "pose"].to_numpy() for s in SETS}
    provisional = np.sort(np.asarray(exclude, dtype=int))
    screens, selected = {}, []  # selected: each round's effects, for the screen's record of its rounds

    def fit_and_screen(excluded):
        data = {s: readings(chain, sensor, s, settings.model, excluded) for s in SETS}
        poses = {s: sensor.table.loc[data[s].rows, "pose"].to_numpy() for s in SETS}
        frame_problem = noise.frame_problem(t_nr, data["optimization"].measured)
        tracker = sensor.kind == "laser_tracker" and settings.tracker_noise is not None and frame_problem is None
        fitted, fitted_poses, thinning = fitted_rows(data["optimization"], poses["optimization"], settings.fit_rows)
        offered = None  # the tracker's noise shape is offered against its noise floor (inf: not known)
        if tracker:
            floor, _, _ = noise_floor.floor_of(fitted.q, fitted.measured, sensor.noise, sensor.point_std(fitted.rows))
            offered = math.inf if floor is None else floor
        selection = select(chain, fitted, sensor.marker, t_nr, base_held, fitted_poses, settings, tracker=offered)
        screens["optimization"] = _screen(selection, fitted, every, every_poses, "optimization", settings)
        selected.append(list(selection.added))
        return (selection, data, poses, fitted, fitted_poses, thinning, frame_problem), screens["optimization"].gross

    turns = gross_errors.settle(fit_and_screen, provisional)
    history = [{**record, "added": added} for record, added in zip(turns.history, selected)]
    (selection, data, poses, fitted, fitted_poses, thinning, frame_problem), excluded = turns.fit, turns.excluded
    # the validation set is screened here, with the final model, after every choice has been made
    screens["validation"] = _screen(selection, fitted, every, every_poses, "validation", settings)
    flagged = {"optimization": excluded, "validation": screens["validation"].gross}
    data["validation"] = readings(chain, sensor, "validation", settings.model, flagged["validation"])
    poses["validation"] = sensor.table.loc[data["validation"].rows, "pose"].to_numpy()
    return Screened(
        selection,
        data,
        poses,
        fitted,
        fitted_poses,
        thinning,
        every,
        every_poses,
        flagged,
        screens,
        provisional,
        history,
        turns.settled,
        frame_problem,
    )


def fitted_rows(data: Readings, poses, limit: int) -> tuple[Readings, np.ndarray, dict]:
    """The optimization readings (n rows) the loop fits, their poses (n,) and the record of how they
    were chosen: every row when there are at most `limit`; else whole poses, one in k in
    measurement order (of their first row), k the smallest that leaves at most `limit` rows, so
    that the rows fitted span the campaign's time and configurations as the set does. When no k
    does (a pose of more rows than that: a continuous log under one label), one row in k."""
    poses = np.asarray(poses)
    n = len(data.rows)
    record = {"limit": int(limit), "rows": n, "of": n, "one_in": 1, "unit": "pose"}
    if n <= limit:
        return data, poses, record
    labels, first, member = np.unique(poses, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(labels), dtype=int)
    rank[order] = np.arange(len(labels))
    per_pose = np.bincount(member, minlength=len(labels))[order]  # rows of each pose, in measurement order
    if per_pose[0] <= limit:  # then some k does: the first pose alone at the latest
        k = 2
        while per_pose[::k].sum() > limit:
            k += 1
        keep = rank[member] % k == 0
        record["one_in"] = k
    else:
        keep = np.arange(n) % math.ceil(n / limit) == 0
        record.update(one_in=math.ceil(n / limit), unit="row")
    record["rows"] = int(keep.sum())
    return data.subset(keep), poses[keep], record


def _screen(selection: Selection, fitted: Readings, every, every_poses, set_name: str, settings) -> gross_errors.Screen:
    """Every measured row of one set judged by the selection's final model (`remaster.loop.gross`),
    fitted on the readings `fitted`."""
    level = settings.gross_errors
    return gross.screen(
        selection,
        fitted,
        every[set_name],
        every_poses[set_name],
        set_name,
        float(level["alpha"]),
        float(level["max_share"]),
    )


def gross_report(
    flagged: Mapping[str, np.ndarray],
    screens: Mapping[str, gross_errors.Screen],
    provisional: np.ndarray,
    history: list[dict],
    settled: bool,
    kept: Mapping[str, Mapping[str, dict]],
    level: Mapping[str, float],
) -> dict:
    """loop_closure.json's `gross_errors`: the table rows flagged in each set ('optimization': the
    rows the final model was fitted without; 'validation'), the level, the rule, each set's screen
    (`gross_errors.Screen.report`), the prepare stage's provisional rows and which of them the final model
    restored (or which it added), the screen's rounds, and the accuracy with the flagged rows."""
    final = set(flagged["optimization"].tolist())
    return {
        "optimization": [int(r) for r in flagged["optimization"]],
        "validation": [int(r) for r in flagged["validation"]],
        "alpha": float(level["alpha"]),
        "max_share": float(level["max_share"]),
        "method": gross.METHOD,
        "isolated": gross_errors.ISOLATED,
        "screens": {s: screen.report() for s, screen in screens.items()},
        "provisional": [int(r) for r in provisional],
        "restored": sorted(int(r) for r in provisional if int(r) not in final),
        "added": sorted(int(r) for r in final - set(provisional.tolist())),
        "rounds": history,
        "settled": settled,
        "with_flagged_rows": {s: dict(pair) for s, pair in kept.items()},
    }


def gross_warnings(
    flagged: Mapping[str, np.ndarray],
    screens: Mapping[str, gross_errors.Screen],
    settled: bool,
    history: Sequence[Mapping] = (),
) -> list[str]:
    """What the screen with the final model says beyond its lists (which the certificate gives with
    the accuracy with and without the rows): a set whose many rows beyond the threshold are a
    systematic departure, a screen that did not settle, and a selection that changed between the
    screen's rounds (`history`, each round's `fitted_without` and `added`): a few rows left out
    decided which effects were added, so the data do not single out one model among them."""
    out = []
    for set_name in SETS:
        screen = screens[set_name]
        if screen.systematic:
            out.append(
                f"{set_name} set: {int(screen.beyond.sum())} of {len(screen.rows)} rows beyond the gross-error "
                f"threshold of the final model: a systematic departure, not gross errors (none left out)"
            )
    if not settled:
        out.append(
            "the gross-error screen did not settle: the final model, fitted without rows "
            f"{[int(r) for r in flagged['optimization']]}, finds rows {screens['optimization'].gross.tolist()}"
        )
    models = [tuple(r["added"]) for r in history if "added" in r]
    if len(set(models)) > 1:
        rounds = "; ".join(
            f"without {len(r['fitted_without'])} row{'' if len(r['fitted_without']) == 1 else 's'}: "
            f"{', '.join(m) or 'nothing'}"
            for r, m in zip(history, models)
        )
        out.append(
            f"the selection changed between the gross-error screen's rounds ({rounds}): which few rows are left "
            "out decides which effects are added, so the data do not single out one model among these; the effects "
            "added are one of them, not the arm's identified effects (loop_closure.json gross_errors/rounds)"
        )
    return out
