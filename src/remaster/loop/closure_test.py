"""Is the loop closed: the held-out RMS of the zero-offset model and of the model after each added or
removed step against the noise floor (`closure_report`, `remaster.loop.noise_floor`), and the
residual Gaussian process's section of loop_closure.json (`gp_report`).
"""

from __future__ import annotations

import math

import numpy as np

from ..inference import evidence
from ..inference.gp.residual import RELEVANT_RANGE
from ..inference.readings import Readings
from ..units import MM
from . import noise_floor
from .candidates import GP
from .selection import BASE_STEP, Selection

# measured on simulated arms whose loop could not close (docs/validation.md, the truth's rank among the
# posterior's draws): the declared error is a size measured on held-out poses, not a model of what is missing
SHAPE_OF_THE_DECLARED_ERROR = (
    "its bounds and claims carry the model error it declares (per command in a bound; in the workspace claims "
    "as a field over the joints where a kernel was fitted to the residual), a size measured on held-out poses, "
    "not a model of what is missing: near the data the bounds can be wider than the arm's errors and the "
    "workspace claim below its 95th percentile (measured on simulated arms: docs/validation.md)"
)


def _closure_steps(selection: Selection) -> list[tuple[str, float, int, tuple | None]]:
    """(name, held-out RMS per axis (m), held-out numbers, a correct model's held-out cumulants:
    `noise_floor.verdict`) of the zero-offset model and of the model after each added or removed
    step, in their order."""
    base = selection.base.cv
    steps = [(BASE_STEP, base.rmse / math.sqrt(3.0), base.held_out_numbers, base.null_cumulants)]
    for r in sorted(selection.rounds, key=_step_order):
        if r["added"]:
            scores = r["scores"][r["added"]]
            steps.append(
                (
                    r["added"],
                    scores["cv_rmse_mm"] * MM / math.sqrt(3.0),
                    scores["cv_held_out_numbers"],
                    scores.get("cv_null_cumulants"),
                )
            )
        elif r.get("removed"):  # the model without it: the removed block's scores were taken against it
            name = "without " + " + ".join([r["removed"], *r.get("removed_with", [])])
            name += f" ({GP} present)" if r.get("with") == GP else ""  # named as the selection's path names it
            scores = r["scores"][r["removed"]]
            steps.append(
                (
                    name,
                    scores["cv_rmse_before_mm"] * MM / math.sqrt(3.0),
                    scores["cv_held_out_numbers_before"],
                    scores.get("cv_null_cumulants_before"),
                )
            )
    return steps


def _noise_model(chosen: dict, floor: float | None, measured) -> tuple[float | None, list[str]]:
    """The chosen noise model's std per axis (m; None for the isotropic noise) at the measured
    positions (n, 3), and what the certificate warns of it: a range/transverse shape not kept, or one
    kept whose std per axis is well above the floor."""
    warnings = []
    if chosen.get("refused"):
        warnings.append(f"the laser tracker's range/transverse noise model was not kept: {chosen['refused']}")
    if chosen.get("chosen") != "range_transverse":
        return None, warnings
    rms = noise_floor.range_transverse_rms(chosen["sigma_range_mm"] * MM, chosen["transverse_growth_per_m"], measured)
    if floor is not None and rms > noise_floor.NOISE_MODEL_RATIO * floor:
        warnings.append(
            f"the chosen range/transverse noise model's std per axis ({rms / MM:.3g} mm) is "
            f"{rms / floor:.1f} x the instrument's noise floor ({floor / MM:.3g} mm): it takes up "
            "error the model lacks; the closure is tested against the floor"
        )
    return rms, warnings


def closure_report(
    selection: Selection,
    data: Readings,
    stated_noise: float | None,
    level: float,
    point_std=None,
) -> dict:
    """The closure test after every round (`remaster.loop.noise_floor`) on the optimization readings: the
    noise floor (stated, repeats, and the instrument's per-point std (n, 3) m or None),
    each round's cross-validated RMS per axis and verdict, each added step's share of the structured
    residual, the final verdict, the chosen noise model's std against the floor, and the warnings
    they call for."""
    floor, repeats, repeated = noise_floor.floor_of(data.q, data.measured, stated_noise, point_std)
    measured_noise = noise_floor.point_std_rms(point_std)
    steps = _closure_steps(selection)
    in_time = (selection.time_blocked or {}).get("rms_per_axis_mm", {})
    rounds = [
        {
            "after": name,
            **noise_floor.verdict(rms, floor, level, numbers, cumulants),
            "time_blocked_rms_per_axis_mm": in_time.get(name),
        }
        for name, rms, numbers, cumulants in steps
    ]
    shares = {
        name: noise_floor.share(before[1], after[1], tested)
        for before, after, tested in zip(steps, steps[1:], rounds)
        for name in (after[0],)
    }
    final = rounds[-1]
    warnings = []
    if final["closed"] is False:
        minor = [
            f"{name} ({100 * value:.0f} %)"
            for name, value in shares.items()
            # effects in the final model only: not a removal step, nor an effect a backward pass took out
            if value is not None and value < noise_floor.MAIN_CAUSE_SHARE and name in selection.added
        ]
        warnings.append(
            f"loop {final['text']}"
            + (
                f"; effects added that explain only a small share of what was left, not its cause: {', '.join(minor)}"
                if minor
                else ""
            )
            + f"; {SHAPE_OF_THE_DECLARED_ERROR}"
        )
    noise_model_rms, said = _noise_model(selection.noise or {}, floor, data.measured)
    warnings += said
    return {
        "stated_noise_mm": None if stated_noise is None else stated_noise / MM,
        "measured_point_std_mm": None if measured_noise is None else measured_noise / MM,
        "noise_model_rms_per_axis_mm": None if noise_model_rms is None else noise_model_rms / MM,
        "repeatability_mm": None if repeats is None else repeats / MM,
        "repeated_configurations": repeated,
        "noise_floor_mm": None if floor is None else floor / MM,
        "level": level,
        "measure": "pose-grouped cross-validated RMS per axis on the optimization set",
        "time_blocked": None
        if selection.time_blocked is None
        else {k: v for k, v in selection.time_blocked.items() if k != "rms_per_axis_mm"},
        "region_folds": None if selection.regions is None else selection.regions.report(),
        "rounds": rounds,
        "share_of_structured_residual": shares,
        "main_causes": [n for n, v in shares.items() if v is not None and v >= noise_floor.MAIN_CAUSE_SHARE],
        "closed": final["closed"],
        "verdict": final["text"],
        "warnings": warnings,
    }


def gp_report(selection: Selection, standard_errors: float) -> dict | None:
    """Where the residual the parametric effects left lives: the GP's hyperparameters, each joint's
    relevance (measured range / lengthscale), the joints it depends on, and the share of that
    residual which is structured (cross-validated fall of its mean square) vs noise, over the pose
    folds and over blocks contiguous in time (`held_out.TimeBlocked`). The joints are named only
    when there is structure to trace: the GP's pose-grouped cross-validated fall exceeds
    `standard_errors` standard errors (`held_out.cv_threshold`). None when the GP was not tried."""
    if selection.gp is None:
        return None
    candidate = selection.gp
    relevance = candidate.relevance()
    columns = [f"q{j + 1}" for j in range(len(relevance))]
    order = np.argsort(-relevance)
    fall = evidence.cv_gain(selection.final.cv, evidence.CrossValidation(candidate.mse, candidate.points))
    structured = fall["cv_mse_fall_in_se"] > standard_errors
    before = float(np.sum(selection.final.cv.mse * selection.final.cv.points))
    after = float(np.sum(candidate.mse * candidate.points))
    return {
        "added": selection.gp_added,
        "hyperparameters": candidate.gp.hyper.report(),
        "relevance": dict(zip(columns, relevance.tolist())),
        "structure_found": bool(structured),
        "depends_on": [columns[j] for j in order if structured and relevance[j] >= RELEVANT_RANGE],
        "most_relevant_joint": columns[int(order[0])] if structured else None,
        "structured_fraction": max(0.0, 1.0 - after / before) if before > 0 else 0.0,
        "cv_gain": fall["cv_gain"],
        "cv_mse_fall_in_se": fall["cv_mse_fall_in_se"],
        "time_blocked": (selection.time_blocked or {}).get("residual_gp"),
        "frame": "robot (the residual rotated back by the final fit's registration)",
        "rows": int(len(candidate.q)),
        "inducing": int(len(candidate.gp.inducing)),
        "rotation_robot_to_sensor": selection.rotation.tolist(),
    }


def _step_order(r: dict) -> tuple[int, int]:
    """Rounds in the order their models were fitted: the GP, tried last, may be recorded in the last
    forward round, before the backward pass's rounds; the backward rounds with the GP present come
    after it."""
    return (2 if r.get("with") == GP else 1 if r["added"] == GP else 0, r["round"])
