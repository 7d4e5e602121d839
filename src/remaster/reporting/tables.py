"""The paper's tables, built from results (never typed by hand), and their text forms.

Each table is a DataFrame whose first column labels the rows; numbers are in the units a
person reads (mm, deg), with the unit in the column or row label. `to_markdown` and `to_latex`
render any such table; `write_table` writes CSV, Markdown and LaTeX side by side.
"""

from __future__ import annotations

import html
import math
import re
from pathlib import PurePath

import numpy as np
import pandas as pd

from ..evaluation import iso9283
from ..files import write_csv, write_text
from ..inference.model import SIGMA, by_parameter, display_value
from ..labels import paper_order, sensor_label
from ..units import shown, shown_to

CAPTIONS = {
    "uncertainty_budget": "Uncertainty budget of the recommended (loop-closed) calibration at the validation "
    "configurations, by Monte Carlo (JCGM 101): a measurement there against the prediction, each independent "
    "source with its u per axis and share of the variance (the posterior of the registration and every "
    "parameter, the residual GP, the model error declared where the loop is not closed, the instrument's "
    "noise); U (95 %) is the 95th percentile of the 3-D distance, with the instrument and without it, and "
    "the share of the validation rows (never fitted) within it checks it. A stated MPE is shown for reference.",
    "iso9283": "ISO 9283 pose characteristics on the validation set (registration from the optimization set): "
    "position accuracy AP (distance from the command to the barycentre of its cycles; with one cycle, "
    "the post-registration error) and position repeatability RP = l-bar + 3 S_l where a configuration "
    f"is measured more than once, mean and worst over the configurations. Not available from a campaign "
    f"of static single-point measurements: {iso9283.CANNOT_GIVE}.",
    "iso9283_poses": "ISO 9283 per pose, as the standard reports it: each configuration of the validation set "
    "measured more than once (the standard's poses, each over 30 cycles; named P1..P5 and listed in that order when "
    "the nominal robot puts the flange at the five points of an ISO 9283 cube: P1 its centre, P2..P5 towards the "
    "corners (-x, -y, -z), (-x, +y, -z), (+x, +y, +z), (+x, -y, +z) of the base frame; otherwise unnamed, in the "
    "order first measured), its cycles, the offset of their "
    "barycentre from the command per axis (APx, APy, APz) and in all (AP), and its repeatability RP = l-bar + "
    "3 S_l; registration from the optimization set. The pooled numbers over every configuration are the "
    "ISO 9283 table's.",
    "certificate_verdict": "Verdict per sensor, its numbers: the acceptance test (Acceptance: the validation "
    "errors checked against the loop-closed model's claim at the validation configurations: the instrument's "
    "noise and the model error the loop declared; a failure with its diagnosis); the mean post-registration "
    "error on the validation set before (the controller's zero-offsets) and after (the loop-closed model, its "
    "effects chosen on the optimization set; never picked by these validation numbers, a failure is the "
    "verdict) with their U, its 95th percentile; and what the loop-closed model claims near the measured "
    "configurations and across the joint limits (the bound on its 95th percentile, 95 % posterior "
    "probability), 'not determined' where the priors, not the data, would decide it. The words (the "
    "model after, the loop's verdict, where the calibration holds, the samplers' cross-check) are the "
    "certificate's line per sensor above this table and certificate.json's verdict_details.",
    "certificate_accuracy": "Accuracy before and after (mm): on the validation set (registration from the "
    "optimization set; U the expanded uncertainty (95 %) of the mean, clustered by pose: CR2, k = t(poses - 1)), "
    "and as the posteriors claim it at the measured configurations, inside the measured joint "
    "ranges and across the joint limits (registration fitted, with the sensor's noise; their p95 is the bound this arm's "
    "95th percentile stays below with 95 % posterior probability).",
    "certificate_corrections": "Zero-offset corrections to add to the controller's zero: the loop-closed model's, "
    "to type in with its other effects, and the zero-offset model's, for a controller that takes "
    "zero-offsets alone; U (95 %) holds the posterior std, the between-design component u_between "
    "(how far a correction moves with the poses measured: jackknife over pose groups) and, for the "
    "loop-closed model where its residual holds a field it lacks, that field's share u_model, k from t at "
    "their effective degrees of freedom; held joints get none.",
    "zero_offsets": "Zero-offsets of every joint from each sensor: MLE (posterior mean) and std (deg).",
    "registration_params": "Registration corrections and the isotropic Gaussian error from each sensor.",
    "zero_offset_trace": "Trace of the zero-offsets in the paper's Metropolis sampler, samples after the dashed line kept",
    "zero_offset_histograms": "Posterior of the zero-offsets (default sampler)",
    "relative_accuracy": "Relative Cartesian accuracy (eq. dist_equation) before (Vernier) and after (Bayesian) "
    "remastering, optimization set.",
    "post_registration_accuracy": "Post-registration absolute position error (eq. post_reg_accuracy) before and "
    "after remastering, optimization set.",
    "theoretical_accuracy_optimization_configs": "Theoretical absolute position error from the uncertainty of the "
    "zero-offsets, unmodeled effects and noise, at the optimization "
    "configurations. Loop-closed: the loop-closed model's posterior (all its parameters and sigma) "
    "propagated the same way.",
    "theoretical_accuracy_random_configs": "Theoretical absolute position error from the uncertainty of the "
    "zero-offsets, unmodeled effects and noise, at random configurations "
    "across the joint space. Loop-closed: its posterior propagated the same way. In every row the "
    "parameters no data can see (joint 1's zero-offset, link lengths the "
    "registration absorbs) are held: robot-frame errors up to a rotation "
    "about base Z; see the workspace table for the claims with them.",
    "theoretical_accuracy_zero_offsets_only": "Theoretical absolute position error from the uncertainty of the "
    "zero-offsets alone, at random configurations (Loop-closed: every "
    "parameter of its effects, without the noise term).",
    "workspace_accuracy": "Where each calibration holds: claimed error (mm) of the paper's and the loop-closed model "
    "at the measured configurations, at random configurations inside the measured joint ranges "
    "and at random configurations across the joint limits (there the parameters the data did not "
    "reach spread by their priors), "
    "propagated from the loop-closed posterior (every draw of its parameters under their "
    "priors, with its noise); registration fitted over the configurations, or in the robot "
    "frame with held zero-offsets drawn from the controller marks' tolerance. 95%: the "
    "error at a random configuration of a random draw; 95% bound: this arm's own 95th "
    "percentile stays below it with 95 % posterior probability. Holds: 'across the joint limits' "
    "when every joint's measured range covers 90 % of its limits and the measured tool axes "
    "spread 30 deg, else 'near the measured configurations'.",
    "workspace_warnings": "What the report warns about each calibration: where its claims hold (the measured "
    "ranges) against the claim across the joint limits, what the next campaign must add, and "
    "parameters the data barely moved from their prior.",
    "validation_accuracy": "Accuracy on the validation set with the optimization set's parameters.",
    "sensor_comparison": "The sensors side by side: estimates, differences in units of their combined "
    "uncertainty, and accuracy.",
    "tcp_scatter": "TCPs of one configuration: Vernier (red), MLE (green), probable (yellow), probable with the "
    "Gaussian error (blue), X-Y, mm from the MLE TCP",
    "post_registration_histograms": "Post-registration errors, Vernier against Bayesian",
    "residuals": "Residuals after remastering against configuration and distance from the base",
    "loop_closure": "Loop closure: what zero-offset remastering leaves, and what is left after the effects the "
    "optimization set supports are added (posterior under the extension priors; the validation "
    "set, read only here, with the optimization fit's parameters).",
    "loop_candidates": "Loop closure: every candidate effect's Laplace evidence gain (nats) under its priors, its "
    "pose-grouped cross-validated fall on the optimization set (and in standard errors), BIC "
    "gain for reference, and the share of the residual it explains, per round; Added says 'yes', or "
    "why not (the criteria it missed, with their numbers, or that the round's added candidate gained more evidence); for a laser "
    "tracker, a last row for its range/transverse noise model (evidence gain against isotropic "
    "noise, or why it was not offered).",
    "controller_offsets": "Zero-offset corrections to add to the controller's zero (true angle = reading + "
    "correction), in degrees and radians, with posterior std and 95 % interval, the between-design "
    "component u_between, the residual field's share u_model (the loop-closed model) and U (95 %, k from t at dof), for the paper's model and the loop-closed "
    "model; held joints get none.",
    "calibrated_files": "The calibration in the robot's own terms, per sensor: calibrated URDFs (same links and "
    "joints as the input), the effects a URDF cannot hold, the controller offsets and, for a "
    "campaign given as a DH table, the calibrated DH tables.",
    "loop_closure_test": "Is the loop closed? After each step, the pose-grouped cross-validated RMS per axis on the "
    "optimization set against the noise floor (the sensor's stated noise, or the spread of "
    "repeated configurations), the share of the structured residual (above the floor) the step "
    "removed, and the joints what is left depends on (residual GP relevance).",
    "loop_residual_joints": "What the parametric effects leave, in the robot frame, against the joint the residual "
    "GP finds most relevant",
    "loop_harmonics_terms": "Loop closure: the joints' cyclic errors (joint_harmonics, when added). Per joint and "
    "harmonic order the data see, the posterior amplitude A and phase of A sin(k q + phase) in degrees, A's std, "
    "the chi-square (2 dof) of the order's two coefficients against 0 with every other term present, its "
    "p-value and the Bonferroni threshold (level / pairs tested); named: supported by the data.",
    "loop_harmonics": "Each joint's cyclic error f_j (joint_harmonics) the loop named: the posterior mean of the "
    "angle error against the joint's reading over its measured range, with its 95 % band",
    "loop_signatures": "The residual against each candidate effect's signature, first round",
    "loop_residuals": "Post-registration errors before and after the loop closure",
    "zero_offsets_over_time": "Zero-offsets of every campaign and sensor over time (deg; std from the "
    "pose-clustered sandwich, which includes what the model lacks; loop_closed: the loop closure's verdict)",
    "drift_between_campaigns": "Drift of the zero-offsets between consecutive campaigns of the same robot and "
    "sensor kind, in units of their combined uncertainty (pose-clustered sandwich "
    "stds, which include what the model lacks); flagged where significant and both loops closed (a loop not "
    "closed carries what its model lacks in its design's proportions: shown, not attributed to the robot).",
    "sensor_agreement": "Agreement of the sensors of each campaign, in units of their combined uncertainty "
    "(pose-clustered sandwich stds); flagged where significant and both loops closed.",
    "loop_parameters_over_time": "Loop closure over time: the zero-offsets refitted with the effects the loop "
    "closure added, and those effects' parameters, per campaign and sensor (display "
    "units in column unit).",
    "loop_parameter_drift": "Drift of the loop-closure parameters between consecutive campaigns of the same robot "
    "and sensor kind, in units of their combined uncertainty; flagged where significant and both loops closed.",
    "loop_parameter_agreement": "Agreement of the sensors of each campaign on the loop-closure parameters (each "
    "sensor's own marker offset and scale left out).",
    "loop_effects_over_time": "Parameters of the effects the loop closure added, over time",
}
HELD = "held"  # marks a parameter not identifiable from the data, held at the controller's value


# --------------------------------------------------------------------------- numbers as a person reads them

_STD = re.compile(r"(?i)(?<![a-z])std(?![a-z])")
# what a std column is the uncertainty of: its name with "std" replaced by one of these
_VALUE_WORDS = ("MLE", "mean", "estimate", "Correction", "value")
_QUANTILE = re.compile(r"^(q?\d+(\.\d+)?%?)(?=[ _(]|$)")
# GUM notation: "u(mean) (mm)" is the standard, "U(mean) (mm)" the expanded uncertainty of "mean (mm)"
_GUM = re.compile(r"^[uU]\((?P<of>[^)]+)\)(?P<rest>.*)$")


def is_uncertainty(column: str) -> bool:
    """Whether a column holds uncertainties (a std, or u(...) / U(...)), not a ratio to one."""
    return bool(_GUM.match(column)) or (bool(_STD.search(column)) and "/" not in column)


def _missing(value) -> bool:
    return value is None or (isinstance(value, (float, np.floating)) and math.isnan(value))


def _decimals_of_std(std: float | None) -> int | None:
    """Decimals that show two significant digits of an uncertainty; None when there is none.
    Counted on the std as shown: 0.0998 shows as 0.10 (two decimals), not 0.100."""
    if std is None or not np.isfinite(std) or std <= 0:
        return None
    decimals = max(0, 1 - math.floor(math.log10(float(std))))
    return max(0, 1 - math.floor(math.log10(round(float(std), decimals))))


def _uncertainty_columns(columns) -> dict[str, str]:
    """{value or quantile column: its std column} by name: "X Std (deg)" holds the uncertainty of
    "X MLE (deg)", "std_a_deg" of "mean_a_deg", "Std (deg)" of "Correction (deg)" and of the
    quantiles "2.5% (deg)" beside it, "U(mean) (mm)" of "mean (mm)"; a ratio ("difference /
    combined std") is no std."""
    names = [str(c) for c in columns]
    lowered = {n.lower(): n for n in names}
    out = {}
    for std in names:
        gum = _GUM.match(std)
        if gum and gum["of"] + gum["rest"] in names:
            out[gum["of"] + gum["rest"]] = std
        if not (_STD.search(std) and is_uncertainty(std)):
            continue
        partners = [std.replace("combined_std", "diff").replace("combined std", "difference")]
        partners += [_STD.sub(word, std) for word in _VALUE_WORDS]
        for partner in partners:
            if partner.lower() in lowered and lowered[partner.lower()] != std:
                out[lowered[partner.lower()]] = std
        unit = std[_STD.search(std).end() :]  # e.g. " (deg)" or "_deg"
        for name in names:
            match = _QUANTILE.match(name)
            if match and name[match.end() :] == unit:
                out.setdefault(name, std)
    return out


_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def _number(value):
    """value as a float when it is one (a number, or a number written as text in a column that
    mixes numbers and words, e.g. read back from CSV); else None."""
    if isinstance(value, (bool, np.bool_)) or value is None:
        return None
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    if isinstance(value, str) and _NUMBER.fullmatch(value.strip()):
        return float(value)
    return None


def formatted(table: pd.DataFrame) -> list[list[str]]:
    """Every cell of a table as text, rounded to what its uncertainty supports (the one
    formatting rule of the Markdown, LaTeX and HTML tables; CSV and Parquet keep full precision):
    an uncertainty (a std column) to two significant digits, the value it belongs to (and the
    quantiles beside it) to the same decimal (`units.shown_to`); a whole number as an integer; any other
    number as `units.shown` (three significant digits); a tiny number (below `units.TINY`) in scientific
    form either way ("-6.59e-07"); text as it is, a missing value as an empty cell."""
    columns = [str(c) for c in table.columns]
    partners = _uncertainty_columns(columns)
    position = {c: i for i, c in enumerate(columns)}
    rows = []
    for row in table.itertuples(index=False):
        cells = []
        for column, value in zip(columns, row):
            number = _number(value)
            if number is None or math.isnan(number):
                cells.append("" if _missing(value) or number is not None else str(value))
                continue
            std = (
                number
                if is_uncertainty(column)
                else (_number(row[position[partners[column]]]) if column in partners else None)
            )
            decimals = _decimals_of_std(std)
            cells.append(shown(number) if decimals is None else shown_to(number, decimals))
        rows.append(cells)
    return rows


def markdown_text(text) -> str:
    """Text as a Markdown page shows it, never as markup: Markdown viewers render raw HTML, so a
    robot's serial or a sensor's name from campaign.yaml holding `<script>` would run; `[...]` would
    make a link and `|` split a table cell."""
    escaped = html.escape(str(text), quote=False)
    for plain, kept in (("|", "\\|"), ("[", "\\["), ("]", "\\]")):
        escaped = escaped.replace(plain, kept)
    return escaped


def to_markdown(table: pd.DataFrame) -> str:
    """A GitHub-style Markdown table (numbers as `formatted` gives them, text as `markdown_text`)."""
    header = "| " + " | ".join(markdown_text(c) for c in table.columns) + " |"
    rule = "|" + "|".join("---" for _ in table.columns) + "|"
    rows = ["| " + " | ".join(markdown_text(cell) for cell in cells) + " |" for cells in formatted(table)]
    return "\n".join([header, rule, *rows]) + "\n"


def _latex_escape(text: str) -> str:
    for plain, escaped in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("_", r"\_"), ("#", r"\#")):
        text = text.replace(plain, escaped)
    return text


def to_latex(table: pd.DataFrame, caption: str, label: str) -> str:
    """A LaTeX table environment with a tabular of every column (numbers as `formatted` gives them)."""
    columns = "|" + "|".join("c" for _ in table.columns) + "|"
    lines = [
        r"\begin{table}",
        r"\centering",
        rf"\caption{{{_latex_escape(caption)}}}",
        rf"\label{{tab:{label}}}",
        rf"\begin{{tabular}}{{{columns}}}",
        r"\hline",
        " & ".join(_latex_escape(str(c)) for c in table.columns) + r" \\",
        r"\hline",
    ]
    lines += [" & ".join(_latex_escape(cell) for cell in cells) + r" \\" for cells in formatted(table)]
    lines += [r"\hline", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def write_table(stem: str | PurePath, table: pd.DataFrame, caption: str, label: str) -> list[PurePath]:
    """Write a table as <stem>.csv (full precision: only the text forms are rounded), <stem>.md and
    <stem>.tex; returns the three paths."""
    stem = PurePath(stem)
    return [
        write_csv(stem.with_suffix(".csv"), table),
        write_text(stem.with_suffix(".md"), f"**{markdown_text(caption)}**\n\n" + to_markdown(table)),
        write_text(stem.with_suffix(".tex"), to_latex(table, caption, label)),
    ]


def zero_offsets_table(summaries: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Table MLE_zero_offsets: per joint, each sensor's MLE (posterior mean) and std in deg.

    summaries: sensor -> `posterior_summary.posterior_summary` table (SI). A parameter held because the data
    cannot determine it is marked 'held' instead of given a number.
    """
    summaries = {sensor: by_parameter(summaries[sensor]) for sensor in paper_order(summaries)}
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


REGISTRATION_ROWS = (
    ("registration.x", "x (mm)"),
    ("registration.y", "y (mm)"),
    ("registration.z", "z (mm)"),
    (SIGMA, "sigma (mm)"),
    ("registration.alpha", "alpha (deg)"),
    ("registration.beta", "beta (deg)"),
    ("registration.gamma", "gamma (deg)"),
)


def registration_params_table(summaries: dict[str, pd.DataFrame], fits: dict[str, dict] | None = None) -> pd.DataFrame:
    """Table MLE_other_params: registration corrections and sigma, MLE and std per sensor, in
    the paper's row order; with `fits` (sensor -> `laplace_report.LaplaceReport`), three more rows: points
    fitted, points without a measurement and points flagged as gross errors by the zero-offset
    model's screen (both left out of this fit; the final list is the loop closure's)."""
    summaries = {sensor: by_parameter(summaries[sensor]) for sensor in paper_order(summaries)}
    rows = []
    for name, label in REGISTRATION_ROWS:
        row = {"Parameter": label}
        for sensor, summary in summaries.items():
            sensor_name = sensor_label(sensor)
            row[f"{sensor_name} MLE"] = display_value(name, summary.loc[name, "mean"])
            row[f"{sensor_name} Std"] = display_value(name, summary.loc[name, "std"])
        rows.append(row)
    counts = (
        ("points fitted", lambda f: f.points_fitted),
        ("points not seen (left out)", lambda f: len(f.marker_not_seen_rows)),
        ("points flagged provisionally as gross errors (left out)", lambda f: len(f.outlier_rows)),
    )
    for label, count in counts if fits else ():
        row = {"Parameter": label}
        for sensor in summaries:
            row[f"{sensor_label(sensor)} MLE"] = str(int(count(fits[sensor])))  # a count, not a measurement
            row[f"{sensor_label(sensor)} Std"] = ""
        rows.append(row)
    return pd.DataFrame(rows)
