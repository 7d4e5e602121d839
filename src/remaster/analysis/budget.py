"""An uncertainty budget per campaign and sensor, GUM style: where the uncertainty of a remastered
position comes from.

The measurand is a marker position the remastered robot predicts at the measured configurations,
compared with a measurement of it (per axis, mm). Its components, each a standard uncertainty u
per axis, combined in quadrature (GUM, uncorrelated components; the registration and the
zero-offsets are correlated through the fit, so their joint row is propagated with their full
covariance and the correlation term is shown):

- sensor noise: the campaign's stated per-axis noise;
- registration and zero-offsets: the Laplace covariance of the paper model's fit propagated
  through its Jacobian, u^2 = mean over the points and axes of diag(J C J^T);
- what the model lacks: the fit's sigma beyond the stated noise, sqrt(sigma^2 - noise^2) (with no
  stated noise, sigma is noise and what the model lacks together); the same after the loop
  closure, from its refit's sigma.

U = k u_c with k = 2. SI inside; the table is in mm.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..campaigns.campaign import Campaign
from ..inference.fit import LaplaceReport, Registration, build_model
from ..labels import sensor_label
from ..loop.report import LoopReport
from ..units import MM

COVERAGE_FACTOR = 2.0
BLOCKS = (("registration", "registration."), ("zero-offsets", "zero_offsets."))


def propagated(jacobian: np.ndarray, covariance: np.ndarray, columns) -> float:
    """Per-axis standard uncertainty (m) of the predicted positions from the parameters `columns`:
    sqrt of the mean of diag(J_c C_cc J_c^T) over the 3n residual components."""
    j = jacobian[:, columns]
    return float(np.sqrt(np.mean(np.einsum("ij,jk,ik->i", j, covariance[np.ix_(columns, columns)], j))))


def budget_rows(
    jacobian: np.ndarray, laplace: LaplaceReport, stated_noise: float | None, loop_sigma: float | None = None
) -> list[dict]:
    """The budget's rows (Component, u per axis (mm), share of u_c^2 (%), source) of one fit.
    jacobian (3n, P) of the residuals at the MAP; stated_noise and loop_sigma in m (or None)."""
    names = laplace.names
    parts = {label: [i for i, n in enumerate(names) if n.startswith(prefix)] for label, prefix in BLOCKS}
    u = {label: propagated(jacobian, laplace.covariance, columns) for label, columns in parts.items() if columns}
    together = propagated(jacobian, laplace.covariance, [i for columns in parts.values() for i in columns])
    sigma = laplace.sigma_mean
    lacks = np.sqrt(max(sigma**2 - stated_noise**2, 0.0)) if stated_noise is not None else None
    noise = stated_noise if stated_noise is not None else sigma
    combined = np.sqrt(noise**2 + (lacks or 0.0) ** 2 + together**2)
    rows = [
        (
            "sensor noise",
            noise,
            "stated in campaign.yaml"
            if stated_noise is not None
            else "not stated: the fit's sigma, which holds what the model lacks too",
        )
    ]
    rows += [(label, value, "the fit's Laplace covariance through its Jacobian") for label, value in u.items()]
    correlation = together**2 - sum(v**2 for v in u.values())
    rows.append(
        (
            "registration x zero-offsets correlation",
            np.sign(correlation) * np.sqrt(abs(correlation)),
            "signed: their joint variance minus the two alone",
        )
    )
    if lacks is not None:
        rows.append(("what the model lacks", lacks, "the fit's sigma beyond the stated noise"))
    out = [
        {
            "Component": c,
            "u per axis (mm)": v / MM,
            "share of u_c^2 (%)": 100 * np.sign(v) * v**2 / combined**2,
            "source": s,
        }
        for c, v, s in rows
    ]
    out.append(
        {
            "Component": "combined u_c",
            "u per axis (mm)": combined / MM,
            "share of u_c^2 (%)": 100.0,
            "source": "root sum of squares",
        }
    )
    out.append(
        {
            "Component": f"expanded U (k = {COVERAGE_FACTOR:g})",
            "u per axis (mm)": COVERAGE_FACTOR * combined / MM,
            "share of u_c^2 (%)": np.nan,
            "source": "about 95 % for a normal distribution",
        }
    )
    if loop_sigma is not None and stated_noise is not None:
        out.append(
            {
                "Component": "what the model lacks after the loop closure",
                "u per axis (mm)": np.sqrt(max(loop_sigma**2 - stated_noise**2, 0.0)) / MM,
                "share of u_c^2 (%)": np.nan,
                "source": "the loop-closed refit's sigma beyond the stated noise",
            }
        )
    return out


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
        rows = budget_rows(model.jacobian(laplace.theta_map), laplace, data.noise, loops[sensor].sigma_after)
        out += [{"Sensor": sensor_label(sensor), **row} for row in rows]
    return pd.DataFrame(out)
