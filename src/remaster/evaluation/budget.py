"""An uncertainty budget per campaign and sensor, GUM style: where the uncertainty of a remastered
position comes from.

The measurand is a marker position the remastered robot (the zero-offset model) predicts at the
measured configurations, compared with a measurement of it (per axis, mm). Each row is a standard
uncertainty u per axis with its type (A: from these data; B: stated), distribution and degrees of
freedom:

- measurement noise: the campaign's stated per-axis noise (B, normal, dof inf); with none stated,
  the fit's sigma instead, which holds the noise and what the model lacks together and is called so
  (A, dof 3n - P - 1: 3n residual components, P parameters and sigma);
- instrument MPE: the sensor's stated maximum permissible error of a coordinate (campaign.yaml
  sensors/<name>/mpe), rectangular, u = MPE / sqrt(3) (B, dof inf); 'not stated' without it. A
  stated noise is part of what the MPE bounds, so counting both is on the safe side;
- fitted parameters: the registration and the zero-offsets together, the Laplace covariance of the
  fit propagated through its Jacobian with its correlations, u^2 = mean over the points and axes of
  diag(J C J^T) (A, dof 3n - P - 1). One row: two blocks that the fit makes share it equally by
  construction are not two findings;
- model discrepancy: the fit's sigma beyond the stated noise, sqrt(sigma^2 - noise^2), the RMS per
  axis of an error that depends on the configuration and repeats with it. Systematic: it is not
  combined in quadrature nor expanded by k; its 95 % bound over the measured configurations, b95 =
  the 95th percentile of the fit's |residual| per axis (the noise inside it, on the safe side), is
  added linearly to U (GUM F.2.4.5, an uncorrected systematic error). Without a stated noise it
  cannot be told from the noise and stays inside the first row. After the loop closure, what the
  loop-closed model still lacks is given the same way, for reference.

u_c is the root sum of squares of the random rows, nu_eff its Welch-Satterthwaite degrees of
freedom, U = k u_c with k = t_0.975(nu_eff) (`remaster.inference.uncertainty`), and U + b95 the
bound with the systematic term. SI inside; the table is in mm.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..campaigns.campaign import Campaign
from ..inference.bounds import QUANTILE
from ..inference.fit import LaplaceReport, Registration, build_model
from ..inference.uncertainty import COVERAGE, coverage_factor, welch_satterthwaite
from ..labels import sensor_label
from ..loop.result import LoopReport
from ..units import MM

FITTED_BLOCKS = ("registration.", "zero_offsets.")
COLUMNS = ["Component", "Type", "Distribution", "u per axis (mm)", "dof", "share of u_c^2 (%)", "source"]


def propagated(jacobian: np.ndarray, covariance: np.ndarray, columns) -> float:
    """Per-axis standard uncertainty (m) of the predicted positions from the parameters `columns`:
    sqrt of the mean of diag(J_c C_cc J_c^T) over the 3n residual components."""
    j = jacobian[:, columns]
    return float(np.sqrt(np.mean(np.einsum("ij,jk,ik->i", j, covariance[np.ix_(columns, columns)], j))))


def _random_components(stated_noise, sigma: float, dof_fit: int, mpe, fitted: float) -> list[tuple]:
    """The random rows (component, type, distribution, u m, dof, source): the measurement noise
    (the fit's sigma when none is stated), the instrument's MPE and the fitted parameters."""
    random: list[tuple] = []
    if stated_noise is not None:
        random.append(("measurement noise", "B", "normal", stated_noise, math.inf, "stated in campaign.yaml"))
    else:
        random.append(
            (
                "residual scatter: noise and model discrepancy together",
                "A",
                "normal",
                sigma,
                dof_fit,
                "no noise stated: the fit's sigma, which cannot tell the sensor's noise from what the model lacks",
            )
        )
    instrument = (
        ("instrument MPE", "B", "rectangular", mpe / math.sqrt(3.0), math.inf, "MPE stated in campaign.yaml / sqrt(3)")
        if mpe is not None
        else (
            "instrument MPE",
            "B",
            "rectangular",
            math.nan,
            math.nan,
            "not stated in campaign.yaml (sensors/<name>/mpe)",
        )
    )
    random.append(instrument)
    random.append(
        (
            "fitted parameters (registration and zero-offsets)",
            "A",
            "normal",
            fitted,
            dof_fit,
            "the fit's Laplace covariance, correlations included, through its Jacobian",
        )
    )
    return random


def _bound_rows(residuals, expanded: float) -> list[dict]:
    """The systematic term's 95 % bound over the measured configurations from the fit's residuals
    (n, 3) m, and U (`expanded`, m) with it added linearly."""
    bound = float(np.quantile(np.abs(np.asarray(residuals)), QUANTILE))
    return [
        _row(
            "model discrepancy, 95 % bound",
            "systematic",
            "",
            bound,
            math.nan,
            math.nan,
            "95th percentile of the fit's |residual| per axis over the measured configurations (noise inside)",
        ),
        _row(
            "U + model discrepancy bound",
            "",
            "",
            expanded + bound,
            math.nan,
            math.nan,
            "the systematic term added linearly (GUM F.2.4.5): what the zero-offset model's prediction "
            "misses by at 95 % of the measured configurations",
        ),
    ]


def budget_rows(
    jacobian: np.ndarray,
    laplace: LaplaceReport,
    stated_noise: float | None,
    residuals: np.ndarray | None = None,
    loop_sigma: float | None = None,
    mpe: float | None = None,
) -> list[dict]:
    """The budget's rows (`COLUMNS`) of one fit (module docstring). jacobian (3n, P) of the
    residuals at the MAP; residuals (n, 3) m at the MAP (for the systematic term's bound; None:
    no bound); stated_noise, loop_sigma and mpe in m (or None)."""
    names = laplace.names
    columns = [i for i, n in enumerate(names) if n.startswith(FITTED_BLOCKS)]
    fitted = propagated(jacobian, laplace.covariance, columns)
    sigma = laplace.sigma_mean
    dof_fit = max(jacobian.shape[0] - len(names) - 1, 1)
    random = _random_components(stated_noise, sigma, dof_fit, mpe, fitted)
    used = [r for r in random if np.isfinite(r[3])]
    combined = math.sqrt(sum(r[3] ** 2 for r in used))
    nu = welch_satterthwaite([r[3] for r in used], [r[4] for r in used])
    k = coverage_factor(nu)
    out = [
        _row(c, t, d, u, dof, 100 * u**2 / combined**2 if np.isfinite(u) else math.nan, src)
        for c, t, d, u, dof, src in random
    ]
    systematic = math.sqrt(max(sigma**2 - stated_noise**2, 0.0)) if stated_noise is not None else None
    if systematic is not None:
        out.append(
            _row(
                "model discrepancy",
                "systematic",
                "depends on the configuration",
                systematic,
                math.nan,
                math.nan,
                "the fit's sigma beyond the stated noise (RMS per axis over the measured configurations); "
                "not in u_c: its bound is added to U",
            )
        )
    out.append(_row("combined u_c", "", "", combined, nu, 100.0, "root sum of squares of the random components"))
    out.append(
        _row(
            f"expanded U (k = {k:.2f})",
            "",
            "",
            k * combined,
            nu,
            math.nan,
            f"{100 * COVERAGE:.0f} %: k = t at the effective degrees of freedom (Welch-Satterthwaite)",
        )
    )
    if systematic is not None and residuals is not None:
        out += _bound_rows(residuals, k * combined)
    if loop_sigma is not None and stated_noise is not None:
        out.append(
            _row(
                "model discrepancy after the loop closure",
                "systematic",
                "depends on the configuration",
                math.sqrt(max(loop_sigma**2 - stated_noise**2, 0.0)),
                math.nan,
                math.nan,
                "the loop-closed refit's sigma beyond the stated noise, for reference (not in U)",
            )
        )
    return out


def _row(component, kind, distribution, u, dof, share, source) -> dict:
    return dict(zip(COLUMNS, (component, kind, distribution, u / MM, dof, share, source)))


def budget_table(
    campaign: Campaign,
    registrations: dict[str, Registration],
    laplaces: dict[str, LaplaceReport],
    loops: dict[str, LoopReport],
) -> pd.DataFrame:
    """The uncertainty budget of every sensor of a campaign (see the module docstring); loops:
    sensor -> the loop closure's report (`LoopReport.read`: its sigma after)."""
    out = []
    for sensor, laplace in laplaces.items():
        data = campaign.sensors[sensor]
        model, _, _ = build_model(campaign.chain, data, registrations[sensor].t_nr, exclude=laplace.outlier_rows)
        laplace.check_names(model.names)
        rows = budget_rows(
            model.jacobian(laplace.theta_map),
            laplace,
            data.noise,
            model.residuals(laplace.theta_map),
            loops[sensor].sigma_after,
            data.mpe,
        )
        out += [{"Sensor": sensor_label(sensor), **row} for row in rows]
    return pd.DataFrame(out)
