"""Everything a calibration hands over for one sensor once its loop is closed: the workspace
claims (`workspace.workspace_accuracy`), the calibrated URDFs and controller offsets
(`exports.calibrated_stage`), the rigid URDF nearest the loop-closed model with every URDF's
distance from it (`rigid_urdf`, in workspace.json's `urdfs`) and, for a campaign given as a DH
table, the calibrated DH tables (and for a UR, its kinematics_config)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from .. import identity
from ..calibration import exports
from ..calibration.prediction import Propagation, loop_calibration, paper_calibration
from ..campaigns.campaign import Campaign
from ..evaluation import rigid_urdf, workspace
from ..inference.laplace_report import LaplaceReport
from ..loop.result import LoopResults


@dataclass(frozen=True)
class CalibratedOutputs:
    """workspace: the claims (its report with the URDFs' distances from the loop model); files:
    URDFs, effects and offsets; rigid_urdf, ik_urdf: rigid.urdf's and ik.urdf's text; dh: {'paper', 'loop': DH table}
    when the campaign gives a DH table, else None; ur: {'paper', 'loop': kinematics_config} for a
    UR (`exports.ur_form`), else None."""

    workspace: workspace.WorkspaceAccuracy
    files: exports.CalibratedFiles
    rigid_urdf: str
    ik_urdf: str
    dh: dict | None
    ur: dict | None = None


def calibrated_outputs_stage(
    campaign: Campaign,
    sensor: str,
    summary: pd.DataFrame,
    laplace: LaplaceReport,
    loop: LoopResults,
    rng: np.random.Generator,
    propagation: Propagation,
) -> CalibratedOutputs:
    """summary: the fit's summary.csv; laplace: its Laplace report; loop: the loop closure's report,
    MCMC samples and residual-GP rows (SI); rng draws the workspace claims' posterior rows and
    noise, with `propagation`'s sizes and seed. The files' names (the loop report's source, the
    samples' label) name them in error messages."""
    claims = workspace.workspace_accuracy(
        campaign.chain,
        campaign.sensors[sensor],
        identity.robot_identity(campaign),
        summary,
        laplace,
        loop,
        rng,
        propagation,
    )
    label = loop.report.source
    files = exports.calibrated_stage(campaign, sensor, summary, loop.report, label=label)
    rigid = rigid_urdf.rigid_urdf_fit(
        campaign,
        sensor,
        paper_calibration(summary, label=label),
        loop_calibration(loop.report, label=label),
        propagation.seed,
    )
    claims = replace(claims, report={**claims.report, "urdfs": rigid.report})
    rigid_text, _ = exports.calibrated_urdf(campaign.chain, rigid.values)
    ik_text, _ = exports.calibrated_urdf(campaign.chain, rigid.ik_values)
    dh = (
        exports.calibrated_dh_tables(campaign, sensor, summary, loop.report, label=label)
        if "dh" in campaign.robot
        else None
    )
    ur = (
        exports.calibrated_ur_configs(campaign, sensor, summary, loop.report, label=label)
        if exports.ur_form(campaign)
        else None
    )
    return CalibratedOutputs(claims, files, rigid_text, ik_text, dh, ur)
