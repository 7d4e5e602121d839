"""The uncertainty budget per campaign and sensor: where the uncertainty of the recommended
calibration's prediction comes from, at the configurations of use, and whether it covers them.

The budget is the acceptance test's claim taken apart (`acceptance.claim_budget`, computed in the
acceptance stage, where the claim's draws are made): the loop-closed model's prediction at the
validation configurations against a measurement there, propagated by Monte Carlo (JCGM 101) from
independent sources, each a row with its u per axis and its share of the variance:

- the calibration: the posterior of the registration and of every parameter of the loop-closed
  model (whole MCMC rows, correlations included);
- the residual GP, when the loop added one (drawn jointly across the configurations);
- the model error the calibration declares, when the loop is not closed;
- the instrument's noise (stated, or the per-point std), or, with neither, the fitted sigma, which
  holds the noise and whatever the model lacks together and is called so.

The measurand is a 3-D distance, so its expanded uncertainty is its 95th percentile over the draws
and configurations (no per-axis U is multiplied up); it is given with the instrument and without it
(the calibrated position's own error), and held against the validation rows, which the fit never
saw: the share of them within it. A stated MPE is shown for reference: it bounds the noise the budget
already holds, so it is not added to it. SI inside; the table is in mm.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from ..labels import sensor_label
from .acceptance import Acceptance

COLUMNS = ["Sensor", "Component", "u per axis (mm)", "share of u_c^2 (%)", "value (mm)", "note"]


def _row(sensor: str, component: str, u=np.nan, share=np.nan, value=np.nan, note: str = "") -> dict:
    return dict(zip(COLUMNS, (sensor_label(sensor), component, u, share, value, note)))


def budget_rows(sensor: str, budget: Mapping) -> list[dict]:
    """The rows (`COLUMNS`) of one sensor's budget (acceptance.json `budget`, see the module docstring).
    A validation set that cannot test (`acceptance.configurations_report`) says so beside its share
    within U: over one or a few configurations that share checks the noise there, not the budget."""
    configurations = budget.get("validation_configurations")
    where = (
        f"{budget['validation_rows']} validation rows"
        if configurations is None
        else f"{budget['validation_rows']} validation rows ({configurations} distinct configurations)"
    )
    within = (
        "rows the fit never saw: about 95 % when the budget holds"
        if budget.get("validation_tests", True)
        else f"not a check of the budget: {where} cannot test it; the share checks the noise at them"
    )
    rows = [_row(sensor, part["source"], part["u_per_axis_mm"], part["share_percent"]) for part in budget["sources"]]
    rows += [
        _row(sensor, "combined u_c", budget["combined_u_per_axis_mm"], 100.0, note="the sources' variances add"),
        _row(
            sensor,
            "U (95 %) of a measurement against the prediction",
            value=budget["U95_distance_mm"],
            note=f"95th percentile of the 3-D distance over {budget['draws']} posterior draws and the {where}",
        ),
        _row(
            sensor,
            "U (95 %) of the calibrated position",
            value=budget["U95_position_distance_mm"],
            note="the same without the instrument",
        ),
        _row(
            sensor,
            "validation rows within U (%)",
            value=100 * budget["validation_within_U95"],
            note=within,
        ),
    ]
    if budget.get("mpe_mm") is not None:
        rows.append(
            _row(
                sensor,
                "instrument MPE (stated)",
                value=budget["mpe_mm"],
                note="for reference: it bounds the noise above, which the budget already holds",
            )
        )
    return rows


def budget_table(acceptances: Mapping[str, Acceptance]) -> pd.DataFrame:
    """The uncertainty budget of every sensor of a campaign (`COLUMNS`); a sensor whose acceptance
    test was not made (too few validation rows) has one row saying so."""
    rows = []
    for sensor, accepted in acceptances.items():
        if accepted.budget is None:
            rows.append(_row(sensor, "no budget", note=accepted.diagnosis_text))
        else:
            rows += budget_rows(sensor, accepted.budget)
    return pd.DataFrame(rows, columns=COLUMNS)
