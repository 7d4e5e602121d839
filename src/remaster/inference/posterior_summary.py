"""What the posterior says per parameter (`posterior_summary`: mean, std and 95 % interval in SI and
display units, and its status; `mode_summary` at the Laplace mode alone where no sampler ran), and
the new zero-offset corrections ready for a controller (`remastering`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .laplace_report import LaplaceReport
from .model import SIGMA, display_scale, display_unit


def moments(samples: pd.DataFrame) -> pd.DataFrame:
    """Per column of posterior samples (draws, parameters): mean, std (ddof 1) and the 95 %
    interval q2.5, q97.5, in the samples' units; one row per parameter. The one summary of
    samples that the paper's fit and the loop closure's refit share."""
    return pd.DataFrame(
        {
            "mean": samples.mean(),
            "std": samples.std(ddof=1),
            "q2.5": samples.quantile(0.025),
            "q97.5": samples.quantile(0.975),
        }
    )


def mode_summary(laplace: LaplaceReport) -> pd.DataFrame:
    """`posterior_summary` of the model at its Laplace mode alone (no samples: std and interval
    undefined): what a calibration needs (mean, status) where no sampler ran."""
    mode = pd.DataFrame([{**dict(zip(laplace.names, laplace.theta_map)), SIGMA: laplace.sigma_map}])
    return posterior_summary(mode, laplace)


def posterior_summary(frame: pd.DataFrame, laplace: LaplaceReport) -> pd.DataFrame:
    """Per parameter: MLE (the posterior mean, as in the paper), std and 95 % interval in SI and
    in display units (mm, deg), and its status; held parameters appear with status 'held'."""
    summary = moments(frame[list(laplace.names) + [SIGMA]])
    summary["status"] = "estimated"
    reasons = laplace.held_reasons or {}
    for name, value in laplace.held.items():
        summary.loc[name] = [value, np.nan, np.nan, np.nan, f"held: {reasons.get(name, 'not identifiable')}"]
    summary = summary.loc[list(laplace.parameters) + [SIGMA]]
    scale = np.array([display_scale(n) for n in summary.index])
    for column in ("mean", "std", "q2.5", "q97.5"):
        summary[f"{column}_display"] = summary[column].astype(float) / scale
    summary["display_unit"] = [display_unit(n) for n in summary.index]
    summary.index.name = "parameter"
    return summary


def remastering(summary: pd.DataFrame, joint_names, campaign: str, sensor: str) -> dict:
    """The new zero-offset corrections (deg) with their uncertainty, ready to type into a controller:
    new zero = old zero + correction. Held joints get no correction and say why. `summary` as
    `posterior_summary` gives it, indexed by parameter or with a parameter column."""
    if "parameter" in summary.columns:
        summary = summary.set_index("parameter")
    joints = []
    for j, joint in enumerate(joint_names):
        row = summary.loc[f"zero_offsets.q{j + 1}"]
        held = row["status"] != "estimated"
        joints.append(
            {
                "joint": joint,
                "correction_deg": float(row["mean_display"]),
                "std_deg": None if held else float(row["std_display"]),
                "interval_95_deg": None if held else [float(row["q2.5_display"]), float(row["q97.5_display"])],
                "status": row["status"],
            }
        )
    return {
        "campaign": campaign,
        "sensor": sensor,
        "convention": "controller zero += correction (deg)",
        "joints": joints,
    }
