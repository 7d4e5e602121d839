"""A calibration certificate per campaign: what a metrologist reads first.

Per sensor: the points used, flagged and not seen; the error before and after, on the validation
set (read only for this final before/after, never for a choice) and as the loop-closed model
claims it inside the measured joint ranges and across the joint limits; the zero-offset corrections
to type into the controller with their expanded uncertainty (95 %); what the calibration is valid
for and the warnings. Every
number comes from the run's result files (`CertificateInputs`); nothing is typed.

The uncertainty of a mean error is pose-clustered: configurations of one pose (the IK solutions
of one target) share most of their error, so the standard uncertainty is the cluster-robust CR2
one (Bell-McCaffrey, `uncertainty.cr2_mean`) and U = k u with k = t_0.975(clusters - 1). Rows of
one configuration (acceptance.json's `configurations`: joint readings within 0.1 deg) share a
cluster too, whatever their pose labels: a configuration measured again under new pose labels is
one error measured again, not new clusters (`error_clusters`).

A validation set that cannot test (acceptance verdict "cannot test": too few distinct
configurations) is a red flag line first among its sensor's warnings, and its verdict column says
why: never a pass.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..evaluation.acceptance import CANNOT_TEST, DIAGNOSES, UNTESTED, Acceptance
from ..evaluation.accuracy import REGISTRATION_AS_FITTED as AS_IS
from ..evaluation.accuracy import VERNIER_LEAST_SQUARES
from ..evaluation.workspace import claim_rows, priors_decide
from ..files import number_or_nan
from ..inference import metrics
from ..inference.cross_check import disagreeing
from ..inference.laplace_report import LaplaceReport
from ..inference.uncertainty import coverage_factor, cr2_mean
from ..labels import sensor_label
from ..loop.result import LoopReport
from ..loop.sides import with_sides
from ..units import MM

# the controller's zero-offsets with the registration that fits them best; the remastered ones
BEFORE, AFTER = VERNIER_LEAST_SQUARES, "Bayesian"


@dataclass(frozen=True)
class CertificateInputs:
    """One sensor's results the certificate reads. laplace: fit/laplace.json; configuration_errors:
    metrics/configuration_errors.csv; loop_residuals: loop_closure/residuals.parquet (m);
    workspace_accuracy: loop_closure/workspace_accuracy.csv; workspace: loop_closure/workspace.json;
    loop: loop_closure.json; controller_offsets: calibrated/controller_offsets.csv; cross_check:
    fit/cross_check.csv (`cross_check.cross_check`: which samplers confirm the fit), None when not read;
    acceptance: acceptance.json (`evaluation.acceptance`: the validation set as the acceptance test),
    None when not read."""

    laplace: LaplaceReport
    configuration_errors: pd.DataFrame
    loop_residuals: pd.DataFrame
    workspace_accuracy: pd.DataFrame
    workspace: dict
    loop: LoopReport
    controller_offsets: pd.DataFrame
    cross_check: pd.DataFrame | None = None
    acceptance: Acceptance | None = None


# What the verdict says of the samplers' cross-check (`second_sampler`)
CONFIRMED = "confirmed by a second sampler"
NOT_CONFIRMED = "the fit is not confirmed by a second sampler"
NOT_CHECKED = "not cross-checked"


@dataclass(frozen=True)
class Certificate:
    """heading: lines naming the campaign, robot, date and sensors; accuracy: one row per sensor
    and model (mm); corrections: per sensor, model (loop-closed, zero-offsets only) and joint, the
    correction with U (95 %) (deg) or 'held'; verdicts: one row per sensor, the numbers of the verdict
    (`VERDICT_COLUMNS`; the report's overview); warnings: plain text; brief: the first screen, a line
    per sensor (`brief_line`); details: per sensor, the verdict's words the brief line and the
    warnings carry (`DETAIL_COLUMNS`: the model "after", the loop's verdict, where it holds, the
    samplers), kept whole in certificate.json."""

    campaign: str
    heading: list[str]
    accuracy: pd.DataFrame
    corrections: pd.DataFrame
    verdicts: pd.DataFrame
    warnings: list[str]
    brief: list[str] = field(default_factory=list)
    details: list[dict] = field(default_factory=list)


def mean_with_uncertainty(errors, poses) -> tuple[float, float, int, int]:
    """(mean, standard uncertainty of the mean, count, degrees of freedom) of errors (n,) clustered
    by pose (n,): u by CR2 (`uncertainty.cr2_mean`), with G - 1 degrees of freedom for G poses; u
    NaN when fewer than two poses."""
    errors, poses = np.asarray(errors, dtype=float), np.asarray(poses)
    seen = np.isfinite(errors) & pd.notna(poses)
    mean, u, clusters = cr2_mean(errors[seen], poses[seen])
    return mean, u, int(seen.sum()), clusters - 1


def error_clusters(rows, poses, acceptance: Acceptance | None) -> np.ndarray:
    """(n,) cluster labels of validation table rows (n,) with pose labels poses (n,): rows of one
    pose, and rows of one configuration (`acceptance.configurations`' groups, where the acceptance
    test counted them), are in one cluster (the connected components of both relations). Without
    the configurations, the poses."""
    rows, poses = np.asarray(rows), np.asarray(poses)
    configurations = (acceptance.configurations or {}) if acceptance is not None else {}
    if not configurations.get("table_rows") or not len(rows):
        return poses
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    group_of_row = dict(zip(configurations["table_rows"], configurations["configuration_of_row"]))
    seen = pd.notna(poses)
    pose_labels, pose_index = np.unique(poses[seen].astype(str), return_inverse=True)
    # a row the test did not count (left out as a gross error) is a configuration of its own
    groups = np.array([group_of_row.get(int(r), -1 - k) for k, r in enumerate(rows[seen])])
    group_labels, group_index = np.unique(groups, return_inverse=True)
    nodes = len(pose_labels) + len(group_labels)
    edges = coo_matrix((np.ones(len(pose_index)), (pose_index, len(pose_labels) + group_index)), shape=(nodes, nodes))
    _, component = connected_components(edges, directed=False)
    out = np.full(len(rows), None, dtype=object)
    out[seen] = component[pose_index]
    return out


def _row(sensor: str, where: str, model: str, errors_mm, poses) -> dict:
    errors_mm = np.asarray(errors_mm, dtype=float)
    seen = np.isfinite(errors_mm)
    errors_mm = errors_mm[seen]
    mean, u, count, dof = mean_with_uncertainty(errors_mm, np.asarray(poses)[seen])
    k = coverage_factor(dof)
    return {
        "Sensor": sensor_label(sensor),
        "Where": where,
        "Model": model,
        "mean (mm)": mean,
        "U(mean) (mm)": k * u,
        "k": k,
        "p95 (mm)": metrics.error_summary(errors_mm, ("p95",))["p95"] if count else np.nan,
        "points": count,
    }


# the claims' rows: configurations of workspace_accuracy.csv -> where (`workspace.CONFIGURATIONS`)
CLAIMED = {
    "optimization": "claimed at the measured configurations",
    "domain": "claimed near the measured configurations",
    "random": "claimed across the joint limits (priors where the data did not reach)",
}


def accuracy_rows(sensor: str, inputs: CertificateInputs) -> list[dict]:
    """Before -> after on the validation set (registration from the optimization set), then what
    the loop-closed posterior claims at the measured configurations, at random configurations inside
    the measured joint ranges and across the joint limits."""
    errors = inputs.configuration_errors
    validation = errors[(errors["set"] == "validation") & (errors["registration"] == AS_IS)]
    # every model's validation rows without those the final model flagged as gross errors (the
    # loop's residuals leave them out already); the warnings give the numbers with them
    flagged = inputs.loop.gross_errors["validation"]
    validation = validation[~validation["row"].isin(flagged)]
    where = "validation set (measured)"
    # the clusters of the mean's U: poses, joined where one configuration carries several pose labels
    clusters = pd.Series(error_clusters(validation["row"], validation["pose"], inputs.acceptance), validation.index)
    rows = [
        _row(
            sensor,
            where,
            label,
            validation.loc[validation["method"] == method, "error_mm"],
            clusters[validation["method"] == method],
        )
        for method, label in ((BEFORE, "controller's zero-offsets"), (AFTER, "remastered zero-offsets"))
    ]
    residuals = inputs.loop_residuals
    after = residuals[(residuals["set"] == "validation") & (residuals["when"] == "after")]
    if len(after):
        norms = np.linalg.norm(after[["x_m", "y_m", "z_m"]].to_numpy(float), axis=1) / MM
        pose_of_row = dict(zip(validation["row"], clusters))
        poses = after["row"].map(pose_of_row).to_numpy()
        rows.append(
            _row(
                sensor,
                where,
                "loop-closed (added: " + with_sides(inputs.loop.effects_added) + ")"
                if inputs.loop.effects_added
                else "loop-closed (no effect added)",
                norms,
                poses,
            )
        )
    claims = inputs.workspace_accuracy
    for configurations, label in CLAIMED.items():
        for model, name in (("paper", "remastered zero-offsets"), ("loop", "loop-closed")):
            claim = claim_rows(claims, model, configurations)
            if len(claim):
                rows.append(
                    {
                        "Sensor": sensor_label(sensor),
                        "Where": label,
                        "Model": name,
                        "mean (mm)": float(claim["mean_mm"].iloc[0]),
                        "U(mean) (mm)": np.nan,
                        "p95 (mm)": float(claim["p95_bound_mm"].iloc[0]),
                        "p95, the data's part (mm)": float(claim["p95_bound_data_mm"].iloc[0])
                        if "p95_bound_data_mm" in claim
                        else np.nan,
                        # a claim is taken over configurations, each drawn `draws` times: count the configurations
                        "points": int(claim["count"].iloc[0]) // max(int(inputs.workspace.get("draws") or 1), 1),
                    }
                )
    return rows


# the corrections' models as the certificate names them, the one to type in first
CORRECTION_MODELS = (
    ("loop", "loop-closed, with its other effects (loop.urdf, loop_effects.yaml)"),
    ("paper", "zero-offsets only (paper.urdf)"),
)


def correction_rows(sensor: str, inputs: CertificateInputs) -> list[dict]:
    """Both models' zero-offset corrections (calibrated/controller_offsets.csv) with U = k u_c, u_c
    the posterior std, the between-design component and (the loop-closed model's, where its residual
    holds a field it lacks) that field's share together and k from t at their effective
    degrees of freedom (`calibrated.controller_offsets`): the loop-closed model's first."""
    offsets = inputs.controller_offsets
    # the loop's points cannot see what a full-pose probe's orientations alone determine: held there at
    # the zero-offset fit's value
    oriented = {
        f"q{n.split('.q')[-1]}" for n in (inputs.laplace.orientation or {}).get("determined_only_with_orientation", ())
    }
    rows = []
    for model, label in CORRECTION_MODELS:
        for index, (_, r) in enumerate(offsets[offsets["model"] == model].iterrows()):
            estimated = r["status"] == "estimated"
            status = r["status"]
            reason = (inputs.laplace.held_reasons or {}).get(f"zero_offsets.q{index + 1}")
            if not estimated and reason:  # both models hold it for the zero-offset fit's reason
                status = f"held: {reason}"
            if model == "loop" and f"q{index + 1}" in oriented:
                status = (
                    f"held at the zero-offset fit's {number_or_nan(r['correction_deg']):.4g} deg, which the orientations "
                    "determine (the loop fits the points alone)"
                )
            rows.append(
                {
                    "Sensor": sensor_label(sensor),
                    "Model": label,
                    "Joint": r["joint"],
                    "Correction (deg)": number_or_nan(r["correction_deg"]) if estimated else np.nan,
                    "U(Correction) (deg)": number_or_nan(r.get("U_deg")) if estimated else np.nan,
                    "u_between (deg)": number_or_nan(r.get("u_between_deg")) if estimated else np.nan,
                    "u_model (deg)": number_or_nan(r.get("u_model_deg")) if estimated else np.nan,
                    "k": number_or_nan(r.get("k")) if estimated else np.nan,
                    "Status": status,
                }
            )
    return rows


def second_sampler(inputs: CertificateInputs) -> tuple[str, dict[str, list[str]]]:
    """(what the verdict says of the samplers' cross-check, {parameter: [methods]} that disagree):
    CONFIRMED, NOT_CONFIRMED (with the disagreements) or NOT_CHECKED (no cross-check read)."""
    if inputs.cross_check is None:
        return NOT_CHECKED, {}
    disagree = disagreeing(inputs.cross_check)
    if disagree:
        return NOT_CONFIRMED, disagree
    return CONFIRMED, {}


def _disagreement_text(disagree: dict[str, list[str]]) -> str:
    return ", ".join(f"{name} ({', '.join(methods)})" for name, methods in disagree.items())


NOT_TESTED = "not tested"  # the acceptance column without acceptance.json
NOT_DETERMINED = (
    "across the joint limits not determined: the data did not reach there, so a bound would be the priors', "
    "not a measurement"
)


NEAR_NOT_DETERMINED = (
    "near the measured configurations not determined either: the priors of the parameters the data barely "
    "moved supply most of the bound there"
)


def acceptance_text(acceptance: Acceptance | None) -> str:
    """The verdict's acceptance column: 'pass', 'fail: <diagnosis>' (`evaluation.acceptance`),
    'cannot test: n distinct configurations of m validation rows ...', or NOT_TESTED."""
    if acceptance is None:
        return NOT_TESTED
    if acceptance.verdict in (UNTESTED, CANNOT_TEST):
        return acceptance.diagnosis_text  # 'not tested: n measured validation rows ...', 'cannot test: ...'
    if acceptance.passed:
        return "pass"
    return f"fail: {DIAGNOSES.get(acceptance.diagnosis, acceptance.diagnosis or 'no diagnosis')}"


def _after(rows: dict) -> dict:
    """The validation row the certificate calls "after": the last validation row, the loop-closed
    model's (recommended before the validation set was read; a failed acceptance test is the
    verdict, not a reason to recommend another model)."""
    validation = [r for (where, _), r in rows.items() if where == "validation set (measured)"]
    return (validation or [{}])[-1]


def _verdict(sensor: str, inputs: CertificateInputs, rows: list[dict]) -> dict:
    by = {(r["Where"], r["Model"]): r for r in rows}
    before = by.get(("validation set (measured)", "controller's zero-offsets"), {})
    after = _after(by)
    inside = by.get((CLAIMED["domain"], "loop-closed"), {})
    limits = by.get((CLAIMED["random"], "loop-closed"), {})
    samplers, disagree = second_sampler(inputs)
    across = bool(inputs.workspace["domain"].get("covers_the_limits", True))
    near = inside.get("p95 (mm)", np.nan)
    near_determined = not priors_decide(near, inside.get("p95, the data's part (mm)", np.nan))
    # each mean beside its U, so that the table rounds it to what U supports (`tables.formatted`)
    return {
        "Sensor": sensor_label(sensor),
        "Before: mean (mm)": before.get("mean (mm)", np.nan),
        "U(Before: mean) (mm)": before.get("U(mean) (mm)", np.nan),
        "After: mean (mm)": after.get("mean (mm)", np.nan),
        "U(After: mean) (mm)": after.get("U(mean) (mm)", np.nan),
        "After: p95 (mm)": after.get("p95 (mm)", np.nan),
        "After: model": after.get("Model", ""),
        # where the priors supply most of the bound near the data too: not determined there either
        "Near the measured configurations: p95 (mm)": near if near_determined else np.nan,
        # where the data did not reach the limits the priors decide the number there: not determined
        "Across the joint limits: p95 (mm)": limits.get("p95 (mm)", np.nan) if across else np.nan,
        "Loop": (inputs.loop.closure or {}).get("verdict") or "",
        # naming the measured ranges (`domain.MeasuredDomain.holds`)
        "Holds": inputs.workspace["domain"]["holds"]
        + ("" if across else f"; {NOT_DETERMINED}")
        + ("" if near_determined else f"; {NEAR_NOT_DETERMINED}"),
        "Samplers": samplers + (f": they disagree on {_disagreement_text(disagree)}" if disagree else ""),
        "Acceptance": acceptance_text(inputs.acceptance),
    }


# The verdict table's columns, read in a minute: the acceptance verdict, the error before and after
# on the validation set with their U, and the two claims, "not determined" where the priors would
# decide them; the words (model, loop, where it holds, samplers) are in the brief line above it.
VERDICT_COLUMNS = (
    "Campaign",
    "Sensor",
    "Acceptance",
    "Before: mean (mm)",
    "U(Before: mean) (mm)",
    "After: mean (mm)",
    "U(After: mean) (mm)",
    "After: p95 (mm)",
    "Near the measured configurations: p95 (mm)",
    "Across the joint limits: p95 (mm)",
)
DETAIL_COLUMNS = ("Sensor", "After: model", "Loop", "Holds", "Samplers")
NOT_DETERMINED_CELL = "not determined"  # a claim the priors would decide (`_verdict`), in the verdict table


def verdict_row(verdict: Mapping) -> dict:
    """The verdict table's row of one sensor's verdict (`_verdict`): its `VERDICT_COLUMNS`, a claim
    the priors would decide written "not determined" (the brief line says why), never a blank."""
    claims = ("Near the measured configurations: p95 (mm)", "Across the joint limits: p95 (mm)")
    return {
        c: (NOT_DETERMINED_CELL if c in claims and not np.isfinite(verdict[c]) else verdict[c])
        for c in VERDICT_COLUMNS
        if c in verdict
    }


def _declared_text(acceptance: Acceptance | None) -> str:
    """What the acceptance test says of a declared model error: '' when none was declared."""
    loop = (acceptance.checks.get("loop") or {}) if acceptance is not None else {}
    declared = loop.get("declared_model_error_mm")
    if not declared:
        return ""
    alone = loop.get("at_noise") or {}
    return f" (as far as the {declared:.3g} mm per axis of model error it declares" + (
        "; not to the sensor's noise)" if alone.get("passed") is False else ")"
    )


def brief_line(sensor: str, inputs: CertificateInputs, verdict: Mapping) -> str:
    """The first screen's line of one sensor: the acceptance verdict, the error after with its U on
    the validation set, where the calibration holds, what is not determined and why, and what the
    next campaign must add (the parameters the data barely moved counted, listed below)."""
    mean, u, p95 = (verdict[k] for k in ("After: mean (mm)", "U(After: mean) (mm)", "After: p95 (mm)"))
    spread = f"U {u:.2g} mm, 95 %" if np.isfinite(u) else "U not determined: the rows are of one configuration or pose"
    after = (
        f"error after {mean:.3g} mm mean ({spread}), p95 {p95:.3g} mm on the validation set"
        if np.isfinite(mean)
        else "no validation error measured"
    )
    workspace = inputs.workspace
    near_determined = NEAR_NOT_DETERMINED not in verdict["Holds"]
    holds = workspace["domain"]["holds"] if near_determined else "at the measured configurations (the validation set's)"
    undetermined = []
    if not workspace["domain"].get("covers_the_limits", True):
        undetermined.append("the accuracy across the joint limits (the data did not reach there)")
    if not near_determined:
        undetermined.append("the accuracy near the measured configurations (the priors supply most of its bound)")
    # the zero-offsets the optimization set cannot tell from the registration and the others (the
    # paper fit's identifiability test; its prior is flat, so a thin set holds them rather than
    # leaving them at a prior): a correction of the controller's value, not a measurement
    held = [n.split(".")[-1] for n in inputs.laplace.held if n.startswith("zero_offsets.")]
    if held:
        undetermined.append(
            f"the zero-offset{'s' if len(held) > 1 else ''} of {', '.join(held)} (held at the controller's value: "
            "the optimization set cannot tell "
            f"{'them' if len(held) > 1 else 'it'} from the registration and the other parameters)"
        )
    dominated = list(workspace.get("prior_dominated") or ())
    if dominated:
        count = len(dominated)
        many = count != 1
        undetermined.append(
            f"{count} parameter{'s' if many else ''} the data barely moved from {'their' if many else 'its'} prior"
        )
    wanted = [w for w in workspace.get("next_campaign_should_add") or () if not w.startswith("poses that move")]
    if dominated:
        wanted.append("poses that move the parameters left to their prior")
    loop = (inputs.loop.closure or {}).get("verdict") or "no closure test"
    samplers = "" if verdict["Samplers"] == CONFIRMED else f"; {verdict['Samplers']}"
    return (
        f"{sensor_label(sensor)}: acceptance {verdict['Acceptance']}{_declared_text(inputs.acceptance)}; "
        f"{after}; model after: {verdict['After: model'] or 'none'}; loop {loop}{samplers}; holds {holds}; "
        f"not determined: {'; '.join(undetermined) or 'nothing'}; "
        f"the next campaign should add: {'; '.join(wanted) or 'nothing'}."
    )


def valid_for(sensor: str, inputs: CertificateInputs) -> str:
    """What the calibration was measured over (`workspace.json`): each joint's measured range in
    degrees (the held joints at their value) and how far the tool axis turned."""
    domain = inputs.workspace["domain"]
    where = (
        f"{domain['ranges']}; every measured tool axis within {domain['tool_axis_spread_deg']:.0f} deg of one direction"
    )
    beyond = (
        "; beyond them, the claim across the joint limits carries the priors of what the data did not reach"
        if not domain["covers_the_limits"]
        else ""
    )
    return (
        f"{sensor_label(sensor)}: valid with this tool plate and marker, in this sensor set-up (registration), "
        f"over the joint ranges measured: {where}{beyond}"
    )


def urdf_line(sensor: str, inputs: CertificateInputs) -> list[str]:
    """Which URDF to load, with each one's distance from the loop-closed model near the measured
    configurations at the marker and at the flange's tools (workspace.json's `urdfs`,
    `evaluation.rigid_urdf`); none without them."""
    urdfs = inputs.workspace.get("urdfs")
    if not urdfs:
        return []
    far = urdfs["distance_from_loop_model_mm"]

    def text(name: str, at: dict = far) -> str:
        d = at[name]
        return f"{name} {d['median_mm']:.2g} mm median, {d['max_mm']:.2g} mm at most"

    tools = urdfs.get("distance_at_tools_mm") or {}
    at_tools = "".join(
        f"; at the tool '{tool}' ({', '.join(f'{1000 * v:g}' for v in urdfs['tools_m'][tool])} mm in the flange "
        f"frame): " + "; ".join(text(name, at) for name in ("rigid.urdf", "ik.urdf", "paper.urdf") if name in at)
        for tool, at in tools.items()
    )
    return [
        f"{sensor_label(sensor)}: a tool that loads a URDF alone should load rigid.urdf, the rigid chain nearest the "
        f"loop-closed model (fitted to its marker and its flange's whole pose); from that model near the measured "
        f"configurations ({urdfs['configurations']} drawn apart from those it was fitted to), at the marker: "
        f"{text('rigid.urdf')}; {text('loop.urdf')} (exact only with loop_effects.yaml "
        f"applied beside it); {text('paper.urdf')}; not followed by any URDF: {urdfs['not_followed']}"
        + (
            f". A closed-form IK solver (intersecting wrist axes) stays exact on ik.urdf (zero-offsets, base and "
            f"tool only): {text('ik.urdf')}"
            if "ik.urdf" in far
            else ""
        )
        + at_tools
    ]


def orientation_line(sensor: str, inputs: CertificateInputs, noise_rad: float | None) -> list[str]:
    """What a full-pose probe's orientations added (fit/laplace.json's `orientation`): the
    zero-offsets they determine that the points alone leave held, how they narrow the others, and
    the orientation error on the validation set before and after the zero-offset model, beside the
    stated noise's (`noise_rad` per component, an angle of RMS sqrt(3) times it); none for points alone."""
    added = inputs.laplace.orientation
    if not added:
        return []
    only = [n.split(".")[-1] for n in added["determined_only_with_orientation"]]
    ratios = [r for n, r in added["information_ratio"].items() if n.startswith("zero_offsets.")]
    errors = inputs.configuration_errors
    validation = errors[(errors["set"] == "validation") & (errors["registration"] == AS_IS)]

    def rms(method: str) -> float:
        if "orientation_error_deg" not in validation:
            return np.nan
        values = validation.loc[validation["method"] == method, "orientation_error_deg"].dropna().to_numpy(float)
        return float(np.sqrt(np.mean(values**2))) if len(values) else np.nan

    determined = (
        f"they determine the zero-offset{'s' if len(only) > 1 else ''} of {', '.join(only)}, which the points "
        "alone leave undetermined"
        if only
        else "they determine no zero-offset that the points alone leave undetermined"
    )
    narrowed = (
        f"; at one sigma they narrow the other zero-offsets' std to {min(ratios):.2g}-{max(ratios):.2g} times the "
        f"points' alone (the fitted sigma {added['sigma_with_orientation_m'] / MM:.2g} mm with them, "
        f"{added['sigma_with_points_alone_m'] / MM:.2g} mm without)"
        if ratios
        else ""
    )
    stated = (
        f" (the stated noise alone: {np.degrees(noise_rad) * np.sqrt(3.0):.2g} deg)" if noise_rad is not None else ""
    )
    before, after = rms(BEFORE), rms(AFTER)
    validated = (
        f"Orientation error on the validation set, RMS angle: {before:.3g} deg with the controller's zero-offsets, "
        f"{after:.3g} deg remastered{stated}"
        if np.isfinite(before) and np.isfinite(after)
        else "No orientation measured on the validation set: the orientation error after is not determined"
    )
    return [
        f"{sensor_label(sensor)}: a full-pose probe, {added['orientations_fitted']} orientations fitted beside the "
        f"points: {determined}{narrowed}. {validated}. The loop closure compares its effects on the positions alone."
    ]


def _mean_with_and_without(errors: pd.DataFrame, method: str, rows) -> tuple[float, float]:
    """(mean error_mm of a method's validation rows (optimization registration), the same without
    the table rows `rows`)."""
    mine = errors[(errors["set"] == "validation") & (errors["registration"] == AS_IS) & (errors["method"] == method)]
    values = mine["error_mm"].to_numpy(dtype=float)
    kept = ~mine["row"].isin(list(rows)).to_numpy()
    return (
        float(np.nanmean(values)) if np.isfinite(values).any() else np.nan,
        float(np.nanmean(values[kept])) if np.isfinite(values[kept]).any() else np.nan,
    )


def gross_error_warnings(label: str, inputs: CertificateInputs) -> list[str]:
    """The rows the loop closure's final model flagged as gross errors (loop_closure.json
    `gross_errors`), in each set: the optimization rows left out of the loop's fit, the validation
    rows with every validation mean error before/after with them and without them; and the
    zero-offset model's rows (fit/laplace.json) that the final model restored."""
    found = inputs.loop.gross_errors
    provisional = list(inputs.laplace.outlier_rows)
    out = []
    optimization, validation = list(found["optimization"]), list(found["validation"])
    if optimization:
        out.append(
            f"{label}: optimization set: {len(optimization)} rows flagged as gross errors by the final model and "
            f"left out of the loop closure's fit (rows {optimization}; loop_closure.json gross_errors)"
        )
    restored = [r for r in provisional if r not in optimization]
    if restored:
        out.append(
            f"{label}: the zero-offset model's screen left rows {restored} out of its own fit; the "
            "final model finds them within the threshold and restored them in the loop closure"
        )
    if validation:
        parts = []
        for method, name in ((BEFORE, "controller's zero-offsets"), (AFTER, "remastered zero-offsets")):
            with_them, without = _mean_with_and_without(inputs.configuration_errors, method, validation)
            parts.append(f"{name} {with_them:.3g} / {without:.3g}")
        kept, after = found["with_flagged_rows"]["validation"]["after"], inputs.loop.after["validation"]
        if kept["mean_mm"] is not None and after["mean_mm"] is not None:  # null: no row to average
            parts.append(f"loop-closed {kept['mean_mm']:.3g} / {after['mean_mm']:.3g}")
        out.append(
            f"{label}: validation set: {len(validation)} rows flagged as gross errors by the final model (rows "
            f"{validation}); validation mean error with them / without them (mm): {'; '.join(parts)}"
        )
    return out


def red_flags(sensor: str, inputs: CertificateInputs) -> list[str]:
    """The line a reader must not miss: a validation set that cannot test the calibration
    (acceptance verdict CANNOT_TEST), with the acceptance test's own words (its first warning)."""
    accepted = inputs.acceptance
    if accepted is None or accepted.verdict != CANNOT_TEST:
        return []
    said = accepted.warnings[0] if accepted.warnings else accepted.diagnosis_text
    return [f"{sensor_label(sensor)}: RED FLAG, no acceptance: {said}"]


def warnings_of(sensor: str, inputs: CertificateInputs) -> list[str]:
    """What the user must know before relying on the calibration: flagged points, the loop
    closure's warnings (not closed against the sensor's noise, nothing explains what is left, a
    refit short of the convergence criteria), the workspace warnings (the claims hold inside the
    measured ranges only, what the next campaign must add, prior-dominated parameters), the held
    joints, any held registration parameter, samplers that disagree (the fit not confirmed), and the
    acceptance test's diagnosis of a failure on the validation set."""
    label = sensor_label(sensor)
    out = []
    _, disagree = second_sampler(inputs)
    if disagree:
        out.append(
            f"{label}: {NOT_CONFIRMED}: the samplers' posterior means disagree beyond the cross-check's "
            f"tolerance on {_disagreement_text(disagree)} (fit/cross_check.csv); the results are the "
            "default sampler's"
        )
    out += gross_error_warnings(label, inputs)
    # which combination the data cannot tell apart, per held parameter (the paper fit's own test)
    out += [f"{label}: {statement}" for statement in inputs.laplace.held_statements]
    held_registration = [n for n in inputs.laplace.held if not n.startswith("zero_offsets.")]
    if held_registration:
        out.append(
            f"{label}: the data do not determine the registration fully: {', '.join(held_registration)} held "
            "(fit/laplace.json, identifiability)"
        )
    out += [f"{label}: loop closure: {w}" for w in inputs.loop.warnings or ()]
    # the first warning of a set that cannot test is the red flag line already (`red_flags`)
    accepted = inputs.acceptance
    said = () if accepted is None else accepted.warnings[1:] if red_flags(sensor, inputs) else accepted.warnings
    out += [f"{label}: {w}" for w in said]
    out += [f"{label}: {w}" for w in inputs.workspace["warnings"]]
    if inputs.workspace["held_note"]:
        out.append(f"{label}: {inputs.workspace['held_note']}")
    return out


def certificate(summary: dict, per_sensor: dict[str, CertificateInputs]) -> Certificate:
    """The certificate of one campaign from its summary (`campaigns.campaign.summarize`) and each
    sensor's results."""
    robot = summary["robot"]
    serial = robot.get("serial")
    heading = [
        f"Robot {robot['name']}"
        + (f", serial {serial}" if serial else ", no serial given")
        + f" ({len(robot['joints'])} joints); measured {summary['date']}; sensors: "
        + ", ".join(f"{sensor_label(s)} ({info['kind']})" for s, info in summary["sensors"].items())
        + "."
    ]
    outside = summary.get("inputs_outside_the_folder") or []
    if outside:
        heading.append(
            "Read from outside the campaign folder (hashed in audit.json; the folder alone does not reproduce "
            f"this certificate): {'; '.join(outside)}."
        )
    accuracy, corrections, verdicts, warnings, brief, details = [], [], [], [], [], []
    for sensor, inputs in per_sensor.items():
        laplace = inputs.laplace
        found = inputs.loop.gross_errors
        flagged = (
            f"{len(found['optimization'])} optimization and {len(found['validation'])} validation "
            "rows flagged as gross errors by the loop closure's final model (left out, listed in "
            "loop_closure.json), "
        )
        heading.append(
            f"{sensor_label(sensor)}: {laplace.points_fitted} points used in the zero-offset fit, {flagged}"
            f"{len(laplace.marker_not_seen_rows)} not seen by the sensor (left out and listed in fit/laplace.json)."
        )
        rows = accuracy_rows(sensor, inputs)
        accuracy += rows
        corrections += correction_rows(sensor, inputs)
        verdict = _verdict(sensor, inputs, rows)
        verdicts.append(verdict_row({"Campaign": summary["campaign"], **verdict}))
        details.append({c: verdict[c] for c in DETAIL_COLUMNS})
        brief.append(brief_line(sensor, inputs, verdict))
        brief += orientation_line(sensor, inputs, summary["sensors"][sensor].get("orientation_noise_rad"))
        warnings += [
            *red_flags(sensor, inputs),
            valid_for(sensor, inputs),
            *urdf_line(sensor, inputs),
            *warnings_of(sensor, inputs),
        ]
    heading.append(
        "Errors are post-registration distances (mm). The validation set was read only for this "
        "before/after; U is the expanded uncertainty (95 %) of a mean, clustered by pose and by "
        "configuration (CR2, k from t with clusters - 1 degrees of freedom; rows whose joint readings agree to "
        "0.1 deg are one configuration, whatever their pose labels); the claims are the loop-closed posterior propagated with the sensor's noise, and a "
        "claim's p95 is the bound this arm's 95th percentile stays below with 95 % posterior "
        "probability; its points are the configurations it is taken over. Corrections: add to the controller's zero (true angle = reading + correction). "
        "Type in the loop-closed model's corrections where the controller takes its other effects too "
        "(loop.urdf, loop_effects.yaml): once those are modelled its zero-offsets are the joints' own; a "
        "controller that takes zero-offsets alone gets the zero-offset model's, which also absorb what "
        "it lacks at the measured poses. Each U (95 %) holds the posterior std and how far the "
        "correction moves with the poses measured (u_between, a jackknife over pose groups) and, where the "
        "loop-closed model's residual holds a field it lacks (the residual GP added, or the loop not closed), "
        "how far that field moves the correction (u_model), k from t "
        "at their effective degrees of freedom; a loop-closed correction whose U is large is traded "
        "against the link geometry, and only their combination (loop.urdf's joint origins) is determined."
    )
    return Certificate(
        summary["campaign"],
        heading,
        pd.DataFrame(accuracy),
        pd.DataFrame(corrections),
        pd.DataFrame(verdicts),
        warnings,
        brief,
        details,
    )


def to_markdown(cert: Certificate) -> str:
    """The certificate as a Markdown page (numbers rounded as every table is)."""
    from .tables import markdown_text
    from .tables import to_markdown as table

    parts = [
        f"# Calibration certificate: {markdown_text(cert.campaign)}",
        "",
        markdown_text(cert.heading[0]),
        "",
        *[f"- {markdown_text(line)}" for line in cert.brief],
        "",
        "## Verdict",
        "",
        table(cert.verdicts.drop(columns="Campaign", errors="ignore")),  # the page names its campaign
        "## Accuracy before and after",
        "",
        table(cert.accuracy),
        "## Zero-offset corrections to apply",
        "",
        table(cert.corrections),
        "## How these numbers were made",
        "",
        *map(markdown_text, cert.heading[1:]),
        "",
        "## Valid for, and warnings",
        "",
    ]
    parts += [f"- {markdown_text(w)}" for w in cert.warnings] or ["- none"]
    return "\n".join(parts) + "\n"
