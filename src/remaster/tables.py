"""The paper's tables, built from results (never typed by hand), and their text forms.

Each table is a DataFrame whose first column labels the rows; numbers are in the units a
person reads (mm, deg), with the unit in the column or row label. `to_markdown` and `to_latex`
render any such table; `remaster.io.write_table` writes CSV, Markdown and LaTeX side by side.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .model import SIGMA, display_scale

CAPTIONS = {
    "zero_offsets": "Zero-offsets of every joint from each sensor: MLE (posterior mean) and std (deg).",
    "registration_params": "Registration corrections and the isotropic Gaussian error from each sensor.",
    "zero_offset_trace": "Trace of the zero-offsets in the paper's Metropolis sampler, samples after the dashed line kept",
    "zero_offset_histograms": "Posterior of the zero-offsets (default sampler)",
}
SENSOR_LABELS = {"motion_capture": "Motion Capture", "laser_tracker": "Laser Tracker"}
HELD = "held"  # marks a parameter not identifiable from the data, held at the controller's value


def sensor_label(name: str) -> str:
    return SENSOR_LABELS.get(name, name.replace("_", " ").title())


def _cell(value, digits: int) -> str:
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, (int, np.integer)):
        return str(value)
    return f"{value:.{digits}f}"


def to_markdown(table: pd.DataFrame, digits: int = 3) -> str:
    """A GitHub-style Markdown table."""
    header = "| " + " | ".join(str(c) for c in table.columns) + " |"
    rule = "|" + "|".join("---" for _ in table.columns) + "|"
    rows = ["| " + " | ".join(_cell(v, digits) for v in row) + " |" for row in table.itertuples(index=False)]
    return "\n".join([header, rule, *rows]) + "\n"


def _latex_escape(text: str) -> str:
    for plain, escaped in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("_", r"\_"), ("#", r"\#")):
        text = text.replace(plain, escaped)
    return text


def to_latex(table: pd.DataFrame, caption: str, label: str, digits: int = 3) -> str:
    """A LaTeX table environment with a tabular of every column."""
    columns = "|" + "|".join("c" for _ in table.columns) + "|"
    lines = [r"\begin{table}", r"\centering", rf"\caption{{{_latex_escape(caption)}}}", rf"\label{{tab:{label}}}",
             rf"\begin{{tabular}}{{{columns}}}", r"\hline",
             " & ".join(_latex_escape(str(c)) for c in table.columns) + r" \\", r"\hline"]
    for row in table.itertuples(index=False):
        lines.append(" & ".join(_latex_escape(_cell(v, digits)) for v in row) + r" \\")
    lines += [r"\hline", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def display_value(name: str, value: float) -> float:
    """A parameter value in its display unit (mm or deg)."""
    return float(value) / display_scale(name)


def _indexed(summary: pd.DataFrame) -> pd.DataFrame:
    return summary.set_index("parameter") if "parameter" in summary.columns else summary


def paper_order(sensors) -> list[str]:
    """Sensors in the paper's column order (motion capture, laser tracker), then the others by name."""
    known = list(SENSOR_LABELS)
    return sorted(sensors, key=lambda s: (known.index(s) if s in known else len(known), s))


def zero_offsets_table(summaries: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Table MLE_zero_offsets: per joint, each sensor's MLE (posterior mean) and std in deg.

    summaries: sensor -> `fit.posterior_summary` table (SI). A parameter held because the data
    cannot determine it is marked 'held' instead of given a number.
    """
    summaries = {sensor: _indexed(summaries[sensor]) for sensor in paper_order(summaries)}
    names = [n for n in next(iter(summaries.values())).index if n.startswith("zero_offsets.")]
    rows = []
    for name in sorted(names, key=lambda n: int(n.rsplit("q", 1)[1])):
        row = {"Zero-Offset": "dtheta" + name.rsplit("q", 1)[1]}
        for sensor, summary in summaries.items():
            label = sensor_label(sensor)
            held = summary.loc[name, "status"] != "estimated"
            row[f"{label} MLE (deg)"] = HELD if held else display_value(name, summary.loc[name, "mean"])
            row[f"{label} Std (deg)"] = HELD if held else display_value(name, summary.loc[name, "std"])
        rows.append(row)
    return pd.DataFrame(rows)


REGISTRATION_ROWS = (("registration.x", "x (mm)"), ("registration.y", "y (mm)"), ("registration.z", "z (mm)"),
                     (SIGMA, "sigma (mm)"), ("registration.alpha", "alpha (deg)"),
                     ("registration.beta", "beta (deg)"), ("registration.gamma", "gamma (deg)"))


def registration_params_table(summaries: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Table MLE_other_params: registration corrections and sigma, MLE and std per sensor, in
    the paper's row order."""
    summaries = {sensor: _indexed(summaries[sensor]) for sensor in paper_order(summaries)}
    rows = []
    for name, label in REGISTRATION_ROWS:
        row = {"Parameter": label}
        for sensor, summary in summaries.items():
            sensor_name = sensor_label(sensor)
            row[f"{sensor_name} MLE"] = display_value(name, summary.loc[name, "mean"])
            row[f"{sensor_name} Std"] = display_value(name, summary.loc[name, "std"])
        rows.append(row)
    return pd.DataFrame(rows)
