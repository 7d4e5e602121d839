"""One transfer pair compared the same way by every transfer benchmark (bench_transfer.py on simulated
campaigns, bench_ur10_transfer.py on the real UR10): a source calibration's models beside complete-model
least squares, applied to a target campaign by `comparing.transfer.transfer_errors` (the source's
kinematics frozen, the target's registration refitted on its optimization rows, the RMS over its
validation rows), and the targets on the pair.

Models on every pair, the same rows for each: nominal (the robot description unchanged), paper (the
zero-offset model), loop (the loop closure's parametric effects; the residual GP is not transferred),
least_squares (zero-offsets, every link's six parameters, the marker offset and joint compliance,
fitted flat on the source's optimization rows: `truth_claims.least_squares_validation`) and
least_squares_rigid (the same without the compliance: shown, not a target).
"""

from __future__ import annotations

import time

import numpy as np

from benchmarks.truth_claims import least_squares_validation
from remaster import identity
from remaster.calibration import prediction
from remaster.comparing.transfer import transfer_errors
from remaster.loop import settings as loop_settings

COMPLETE = ("link_geometry", "marker_offset", "joint_compliance")
RIGID = ("link_geometry", "marker_offset")  # the same least squares without the compliance: shown, not a target
WITHIN = 1.1  # the loop-closed model's transfer RMS over the baseline's it should stay under
SIGNIFICANT = 2.0  # standard errors of the paired difference beyond which "farther" is told by the rows
MODELS = ("nominal", "paper", "loop", "least_squares", "least_squares_rigid")


def models_of(calibration, label: str) -> dict:
    """A calibration (`api.Calibration`) as the models a transfer applies, with least squares
    beside: {'models': {model: prediction.Calibration}, 'least_squares_parameters', 'least_squares_seconds'}."""
    started = time.perf_counter()
    settings = loop_settings.from_config(calibration.settings)
    fitted = {
        name: least_squares_validation(
            calibration.campaign,
            calibration.sensor,
            calibration.registration,
            calibration.laplace,
            settings,
            extensions,
        )
        for name, extensions in (("least_squares", COMPLETE), ("least_squares_rigid", RIGID))
    }
    models = {
        "nominal": prediction.Calibration("nominal"),
        "paper": prediction.paper_calibration(calibration.summary, label=label),
        "loop": prediction.loop_calibration(calibration.loop.report, label=label),
        **{name: f["calibration"] for name, f in fitted.items()},
    }
    return {
        "models": models,
        "least_squares_parameters": fitted["least_squares"]["parameters"],
        "least_squares_seconds": time.perf_counter() - started,
    }


def target_of(campaign, sensor: str, excluded) -> prediction.Calibrated:
    """A campaign as a transfer's target: its readings of `sensor`, leaving out the rows `excluded`
    (its own zero-offset fit's gross errors)."""
    return prediction.Calibrated(
        campaign.name,
        campaign.date.isoformat(),
        identity.robot_identity(campaign),
        campaign.sensors[sensor],
        campaign.chain,
        {},
        excluded,
    )


def rms_mm(errors: np.ndarray) -> float:
    return float(np.sqrt(np.mean(errors**2)) * 1e3) if len(errors) else float("nan")


def pair_rms(models: dict, target: prediction.Calibrated) -> dict:
    """Each model's transfer RMS on the target (`<model>_rms_mm`, mm), the validation rows used
    (`count`) and, row by row, the loop-closed model's squared error less the zero-offset model's:
    its mean and the mean's standard error (`loop_minus_paper_ms_mm2`, `loop_minus_paper_se_mm2`,
    mm^2; NaN with fewer than two rows)."""
    row, errors = {}, {}
    for model, calibration in models.items():
        errors[model] = transfer_errors(calibration, target)
        row[f"{model}_rms_mm"], row["count"] = rms_mm(errors[model]), len(errors[model])
    paired = (errors["loop"] ** 2 - errors["paper"] ** 2) * 1e6 if {"loop", "paper"} <= set(errors) else np.empty(0)
    row["loop_minus_paper_ms_mm2"] = float(paired.mean()) if len(paired) > 1 else float("nan")
    row["loop_minus_paper_se_mm2"] = (
        float(paired.std(ddof=1) / np.sqrt(len(paired))) if len(paired) > 1 else float("nan")
    )
    return row


def verdict(row: dict, nominal_in_baseline: bool = False) -> dict:
    """The targets on one pair: the loop-closed model within WITHIN x the baseline (least squares,
    or with `nominal_in_baseline` the better of it and the nominal model), below the nominal model
    and no farther than the zero-offset model (as measured, and beyond what the rows tell)."""
    baseline = row["least_squares_rms_mm"]
    if nominal_in_baseline:
        baseline = min(baseline, row["nominal_rms_mm"])
    ratio = row["loop_rms_mm"] / baseline
    return {
        "baseline_rms_mm": baseline,
        "loop_over_baseline": ratio,
        "within_baseline": bool(ratio <= WITHIN),
        "below_nominal": bool(row["loop_rms_mm"] < row["nominal_rms_mm"]),
        "not_above_zero_offset": bool(row["loop_rms_mm"] <= row["paper_rms_mm"]),
        # farther by more than the target's validation rows can tell (two standard errors of the
        # paired difference): a loop that added nothing differs from the zero-offset fit only by its refit
        "not_significantly_above_zero_offset": bool(
            not row.get("loop_minus_paper_ms_mm2", 0.0) > SIGNIFICANT * row.get("loop_minus_paper_se_mm2", 0.0)
        ),
    }
