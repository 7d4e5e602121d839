"""Everything a calibration hands over for one sensor once its loop is closed: the workspace
claims (`workspace.workspace_accuracy`), the calibrated URDFs and controller offsets
(`exports.calibrated_stage`) and, for a campaign given as a DH table, the calibrated DH tables."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import identity
from ..calibration import exports
from ..campaigns.campaign import Campaign
from ..evaluation import workspace
from ..inference.fit import LaplaceReport
from ..loop.result import LoopReport


@dataclass(frozen=True)
class CalibratedOutputs:
    """workspace: the claims; files: URDFs, effects and offsets; dh: {'paper', 'loop': DH table}
    when the campaign gives a DH table, else None."""

    workspace: workspace.WorkspaceAccuracy
    files: exports.CalibratedFiles
    dh: dict | None


def calibrated_outputs_stage(
    campaign: Campaign,
    sensor: str,
    summary: pd.DataFrame,
    laplace: LaplaceReport,
    loop_report: LoopReport,
    loop_samples: pd.DataFrame,
    loop_gp_rows: pd.DataFrame,
    rng: np.random.Generator,
    *,
    n_draws: int,
    n_random: int,
    seed: int,
    samples_label: str = "",
    loop_label: str = "",
) -> CalibratedOutputs:
    """summary: the fit's summary.csv; laplace, loop_report: its Laplace and loop-closure reports;
    loop_samples, loop_gp_rows: the loop's MCMC samples and residual-GP rows (SI); rng draws the
    workspace claims' posterior rows and noise; labels name the files in error messages."""
    claims = workspace.workspace_accuracy(
        campaign.chain,
        campaign.sensors[sensor],
        identity.robot_identity(campaign),
        summary,
        laplace,
        loop_report,
        loop_samples,
        rng,
        n_draws=n_draws,
        n_random=n_random,
        seed=seed,
        label=samples_label,
        loop_gp_rows=loop_gp_rows,
    )
    files = exports.calibrated_stage(campaign, sensor, summary, loop_report, label=loop_label)
    dh = (
        exports.calibrated_dh_tables(campaign, sensor, summary, loop_report, label=loop_label)
        if "dh" in campaign.robot
        else None
    )
    return CalibratedOutputs(claims, files, dh)
