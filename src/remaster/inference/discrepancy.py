"""The paper's parameters with an uncertainty that includes what the model lacks (model discrepancy).

The paper's posterior treats every residual as independent noise. When the model lacks an effect
(compliance, link geometry, ...) the residual is shared by the configurations of a pose and smooth
over the joint space, so some posterior stds are too small and two campaigns of one unchanged
robot look different (false drift flags); others are too large.

The pose-clustered sandwich covariance (Liang & Zeger 1986; the "cluster-robust" covariance of
least squares) does not assume the residuals independent within a pose, nor the model right:

    C = G / (G - 1) B^-1 M B^-1,   B = J^T J,   M = sum over poses g of s_g s_g^T,   s_g = J_g^T r_g,

J (3n, P) = d predicted / d theta at the paper's fit, r its residuals, G the number of poses. With
independent residuals it is the paper's covariance sigma^2 B^-1 in expectation. The means stay
the paper's posterior means; only the stds change.

A Gaussian-process discrepancy in the model (Kennedy & O'Hagan 2001: generalised least squares
with the residual GP's covariance) was tried first and rejected: on 20 fleet copies of
kuka-compliance the drift z of joint 7 still spread 2.2 (joint 6's std shrank to a tenth, the GP
having no use for joint 6), against 0.9-1.2 for every joint with the sandwich (docs/methods.md,
"Model discrepancy in the comparison across campaigns").

The paper's tables keep the paper's posterior; the comparison across campaigns (zero-offsets over
time, drift, sensor agreement) uses these stds.

SI inside (m, rad).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..campaigns.campaign import Campaign
from . import metrics
from .blocks import BlockModel
from .fit import Registration, build_model
from .laplace_report import LaplaceReport
from .model import by_parameter, display_scale

SOURCE = "paper posterior mean; std from the pose-clustered sandwich covariance"
SANDWICH_STEP = 1e-7  # central differences of the Jacobian (SI units of each parameter)


def sandwich_covariance(jacobian, residuals, poses) -> np.ndarray:
    """(P, P) pose-clustered sandwich covariance: jacobian (3n, P) of the predictions, residuals
    (n, 3) m, poses (n,) labels; needs at least two poses."""
    r = np.asarray(residuals, dtype=float)
    j = np.asarray(jacobian, dtype=float)
    labels, group = np.unique(np.asarray(poses), return_inverse=True)
    if len(labels) < 2:
        raise ValueError("a sandwich covariance by pose needs at least two poses")
    scores = np.zeros((len(labels), j.shape[1]))
    np.add.at(scores, group.ravel(), np.einsum("nap,na->np", j.reshape(len(r), 3, -1), r))
    bread = np.linalg.inv(j.T @ j)
    return len(labels) / (len(labels) - 1) * bread @ (scores.T @ scores) @ bread


def discrepancy_summary(model: BlockModel, theta, poses, summary: pd.DataFrame) -> tuple[pd.DataFrame, dict]:
    """The fit's summary (`posterior_summary.posterior_summary`, SI) with every estimated parameter's std and 95 %
    interval (mean +- 1.96 std) from the sandwich at theta (P,), the paper's fit of `model`
    (outliers out); poses (n,) the pose of each of the model's readings. And a JSON-ready report: each std over
    the paper posterior's."""
    theta = np.asarray(theta, dtype=float)
    # a full-pose probe's orientations are rows of their reading's pose too
    rows = model.row_readings
    jacobian = model.weighted_jacobian(theta, SANDWICH_STEP)
    covariance = sandwich_covariance(jacobian, model.weighted_residuals(theta), np.asarray(poses)[rows])
    std = np.sqrt(np.diag(covariance))
    out = by_parameter(summary).copy()
    names = list(model.names)
    paper_std = out.loc[names, "std"].astype(float).to_numpy()
    mean = out.loc[names, "mean"].astype(float).to_numpy()
    out.loc[names, "std"] = std
    out.loc[names, "q2.5"] = mean - metrics.Z95 * std
    out.loc[names, "q97.5"] = mean + metrics.Z95 * std
    scale = np.array([display_scale(n) for n in out.index])
    for column in ("mean", "std", "q2.5", "q97.5"):
        out[f"{column}_display"] = out[column].astype(float) / scale
    out["source"] = SOURCE
    out.index.name = "parameter"
    report = {
        "source": SOURCE,
        "poses": int(len(np.unique(poses))),
        "rows": int(len(poses)),
        "std_over_paper_std": dict(zip(names, (std / paper_std).tolist())),
    }
    return out.reset_index(), report


def discrepancy_stage(
    campaign: Campaign, sensor: str, registration: Registration, laplace: LaplaceReport, summary: pd.DataFrame
) -> tuple[pd.DataFrame, dict]:
    """`discrepancy_summary` of one sensor of a campaign after its fit, at the Laplace fit's MAP
    (the model the fit had: its outliers left out)."""
    data = campaign.sensors[sensor]
    model, _, _ = build_model(
        campaign.chain,
        data,
        registration.t_nr,
        exclude=laplace.outlier_rows,
        orientation_weight=laplace.orientation_weight,
    )
    laplace.check_names(model.names)
    poses = data.table.loc[model.data.rows, "pose"].to_numpy()
    out, report = discrepancy_summary(model, laplace.theta_map, poses, summary)
    report.update(campaign=campaign.name, sensor=sensor)
    return out, report
