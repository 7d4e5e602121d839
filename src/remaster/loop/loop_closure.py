"""Loop closure: what the zero-offset model leaves in the residuals, named and removed.

Per campaign and sensor, after the zero-offset fit, on the OPTIMIZATION set only:

1. Diagnose: for each candidate block (`parameter_blocks.EXTENSIONS`; drift only when the table has a
   time or temperature column), fit current + candidate at its posterior mode under the
   extension priors (`remaster.robot.priors`, `remaster.inference.evidence`) and score it by
   - its Laplace evidence gain, log Z(with it) - log Z(current): the priors make the extended
     model proper, so an effect must explain more than its parameters' prior room costs;
   - its pose-grouped K-fold cross-validation: the paired fall of the held-out mean squared
     residual over the same folds, in units of its standard error over the folds;
   - its BIC gain, for reference (BIC counts 3n independent residuals; where residuals are
     shared by the configurations of a pose it overstates the evidence, which the
     cross-validation by pose does not);
   - its signature: the residual of the current fit against the change in the prediction the
     candidate makes (`explained_fraction`, the share of the current residual it removes).
2. Decide: greedy forward selection. Among the candidates whose evidence gain exceeds
   `min_log_evidence_gain` AND whose cross-validated fall exceeds `cv_standard_errors` standard
   errors, add the one of largest evidence gain, refit, and repeat with the others. When no
   parametric effect passes, a backward pass takes out any added block that would no longer pass
   offered to the model without it. Then the residual Gaussian process over the joints
   (`remaster.inference.gp.residual`) is tried by the same two tests; fitted or not, it says which
   joints what is left depends on. When it is added, every parametric block is scored again with
   the GP present, the parameters integrated together with it (`remaster.inference.gp.with_parameters`), and
   a block that only stood in for what the GP explains is taken out. Last, a laser tracker's noise
   is offered as it is, range and transverse growing with distance (`remaster.noise`), against the
   isotropic noise by the same evidence threshold, for what the residual model leaves (with the GP
   present when it was added): chosen before it, an anisotropic noise takes up model error.
   After every step the closure test (`remaster.loop.noise_floor`) compares the cross-validated residual
   with the sensor's noise and says what share of the structured residual the step removed.
3. Refit the final model by MCMC (independence Metropolis, sigma integrated out, from a proposal
   that follows where the posterior leaves its Laplace approximation; where that misses the
   project's convergence criteria, emcee's ensemble run longer until it meets them, or reported
   as not converged) so
   that every parameter carries uncertainty; say which parameters the data barely moved from
   their prior.
   Before the refit, gross errors are screened with the final model (`remaster.loop.gross`): every
   optimization row, those the zero-offset model's screen left out included, at the level
   `outliers/alpha`; when the rows it finds are not those the loop was fitted without, steps 1-2 run
   again without them, until they are (bounded), so the model, its closure test and its refit are
   computed without exactly the rows listed.
4. Only then the VALIDATION set: its rows screened the same way with the final model, then
   accuracy before (zero-offset model) and after (the selected model), each with the optimization
   fit's parameters and registration, without the rows flagged as gross errors (and, in the table
   and `gross_errors`, with them). Nothing is selected, tuned or stopped on it.

The steps live in `selection` (1, 2; `screened_selection` repeats them without the rows their
final model flags), `refit` (3) and here (4, the report; `closure_test` its test of whether the loop
is closed); `settings` reads the configuration, `report` is loop_closure.json typed, `frames` the
long tables of signatures and residuals; the campaign's tables are `remaster.reporting.tables_loop`.

Accuracy measures (per set, in mm): post-registration RMSE sqrt(mean |E_i|^2) over the points,
the RMS per axis (comparable to sigma and the sensor noise), the paper's mean post-registration
error mean |E_i|, and the paper's relative error |d(ref) - d(model)| over the pairs of
configurations of each pose (`remaster.inference.metrics`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

from ..campaigns.campaign import SETS, Campaign, SensorData
from ..files import write_csv, write_parquet
from ..inference import evidence, fit
from ..inference.gp import loop_candidate
from ..inference.laplace_report import LaplaceReport
from ..inference.model import SIGMA
from ..inference.posterior_sampling import samples_frame
from ..inference.readings import Readings, readings
from ..robot.kinematics import KinematicChain
from ..robot.priors import priors_from
from ..units import MM
from . import harmonics, joint_form
from .closure_test import closure_report, gp_report
from .fitted import accuracy
from .harmonics import harmonics_report
from .held_out import cv_threshold, fold_warning
from .jackknife import departed_groups_warning, too_few_warning, zero_offset_jackknife
from .link_priors import link_prior_scale, scaled_priors
from .long_tables import residuals_frame, signatures_frame
from .model_error_share import JointField, not_computed_warning, zero_offset_model_error
from .refit import parameter_table, refit, zero_offset_shifts
from .result import LoopReport
from .scoring import Signature, symptom_text
from .screened_selection import Screened, fitted_rows, gross_report, gross_warnings, select_screened
from .selection import Selection
from .settings import LoopSettings

MEASURES = (
    ("rmse_mm", "post-registration RMSE (mm)"),
    ("rms_per_axis_mm", "RMS per axis (mm)"),
    ("mean_mm", "mean post-registration error (mm)"),
    ("relative_mean_mm", "mean relative error (mm)"),
)


def before_after_table(
    before: dict,
    after: dict,
    sigma_before: float,
    sigma_after: float,
    parameters: tuple[int, int],
    kept: Mapping[str, Mapping[str, dict]] | None = None,
    flagged: Mapping[str, np.ndarray] | None = None,
) -> pd.DataFrame:
    """The report's table: accuracy on both sets (without the rows flagged as gross errors), sigma
    and parameter count, before (zero-offset model) and after (with the effects added); then, for
    a set with flagged rows, the same measures with them (kept: {set: {'before', 'after'}})."""
    rows = [("sigma (mm)", sigma_before / MM, sigma_after / MM), ("free parameters", parameters[0], parameters[1])]
    for set_name in SETS:
        for key, label in MEASURES:
            rows.append((f"{set_name}: {label}", before[set_name][key], after[set_name][key]))
    for set_name, pair in (kept or {}).items():
        count = len((flagged or {}).get(set_name, ()))
        for key, label in MEASURES:
            rows.append(
                (
                    f"{set_name} with its {count} rows flagged as gross errors: {label}",
                    pair["before"][key],
                    pair["after"][key],
                )
            )
    return pd.DataFrame(rows, columns=["Quantity", "Before (zero-offsets)", "After (with effects)"])


@dataclass(frozen=True, eq=False)
class LoopClosure:
    """report: loop_closure.json; table: before/after; signatures: {round: {candidate: Signature}};
    residuals: {'before'|'after': {set: (n, 3) m}}; samples: the MCMC refit (SI) or None;
    gp: the residual GP's training rows when it was tried (`loop_candidate.training_frame`), else an
    empty frame; rows: {set: (n,) the sensor table's row of each residual}."""

    report: LoopReport
    table: pd.DataFrame
    signatures: dict[int, dict[str, Signature]]
    residuals: dict[str, dict[str, np.ndarray]]
    samples: pd.DataFrame | None
    gp: pd.DataFrame = field(default_factory=pd.DataFrame)
    rows: dict[str, np.ndarray] = field(default_factory=dict)

    def write(self, report, table, signatures, residuals, samples, gp) -> None:
        """Write the loop closure's six files at these paths: loop_closure.json, the before/after CSV,
        and the signatures (`long_tables.signatures_frame`), residuals (`long_tables.residuals_frame`, with the
        rows), MCMC samples (an empty table without them) and residual-GP training rows as Parquet."""
        self.report.write(report)
        write_csv(table, self.table)
        write_parquet(signatures, signatures_frame(self.signatures))
        write_parquet(residuals, residuals_frame(self.residuals, self.rows))
        write_parquet(samples, self.samples if self.samples is not None else pd.DataFrame())
        write_parquet(gp, self.gp)


def _residual_section(selection: Selection, chain, data: Readings, marker, t_nr, settings: LoopSettings):
    """loop_closure.json's `residual_gp` (`gp_report`), with where what is left lives in the joints'
    own terms when the GP found structure (`joint_form.joint_error_form`, a diagnostic)."""
    section = gp_report(selection, cv_threshold(settings))
    if section is not None:
        section["joint_error_form"] = (
            joint_form.joint_error_form(selection, chain, data, marker, t_nr, settings.min_log_evidence_gain)
            if section["structure_found"]
            else {"computed": False, "why": "the residual GP found no structure to trace"}
        )
    return section


def _joint_field(gp_section: dict | None, selection: Selection, chain, data: Readings, marker, t_nr):
    """The residual GP in joint-error form where the evidence prefers it (`model_error_share.JointField`,
    the directions at the final model's values), else None."""
    report = (gp_section or {}).get("joint_error_form")
    if not JointField.taken(report):
        return None  # before the directions: they cost a Jacobian at every reading
    directions = joint_form.joint_directions(chain, data, marker, t_nr, selection.final.values())
    return JointField.preferred(report, directions)


def _zero_offset_spreads(
    screened: Screened,
    closed: bool | None,
    settings: LoopSettings,
    gp_section: dict | None = None,
    joint_field: JointField | None = None,
) -> tuple[dict, dict]:
    """What the certificate's U holds beyond the posterior: how far the zero-offsets move with the
    poses measured ({'paper', 'loop': `jackknife.zero_offset_jackknife`}), and how far a residual
    field the final model lacks moves them (`model_error_share.zero_offset_model_error`; in
    joint-error form where `joint_field` is given; where that form is preferred but not taken, why:
    `joint_form_not_taken`)."""
    selection, poses = screened.selection, screened.fitted_poses
    between = {
        name: zero_offset_jackknife(model, poses, settings.jackknife_groups)
        for name, model in (("paper", selection.base), ("loop", selection.final))
    }
    hyper = selection.gp.gp.hyper if selection.gp is not None else None
    share = zero_offset_model_error(selection.final, hyper, closed, selection.gp_added, joint_field)
    return between, share | (joint_form_not_taken(gp_section) if share.get("computed") else {})


def joint_form_not_taken(gp_section: dict | None) -> dict:
    """Why `model_error_share` takes the free form where the evidence prefers the joint-error form
    (a joint's lengthscale on the form's lower bound, `JointField.at_lower_bound`), else {}."""
    report = (gp_section or {}).get("joint_error_form") or {}
    short = JointField.at_lower_bound(report) if report.get("preferred") == "joint_error" else []
    if not short:
        return {}
    return {
        "joint_form_not_taken": f"the joint-error form is preferred, but {', '.join(short)} ended on its shortest "
        "lengthscale: there f_j takes up structure shorter than a joint error, so the free form is taken"
    }


def _warnings(closed: dict, screened: Screened, gp_section: dict | None, mcmc, settings: LoopSettings) -> list[str]:
    """The report's warnings: the closure test's, too few poses for the folds, nothing explaining
    what is left (with where it lives), the gross-error screen's, and an MCMC refit short of the
    convergence criteria."""
    warnings = list(closed["warnings"])
    few_poses = fold_warning(screened.fitted_poses, settings)
    if few_poses:
        warnings.append(few_poses)
    thinning = screened.thinning
    if thinning["rows"] < thinning["of"]:
        warnings.append(
            f"the loop closure fitted {thinning['rows']} of the optimization set's {thinning['of']} rows (one "
            f"{thinning['unit']} in {thinning['one_in']}, in measurement order; loop_closure/fit_rows = {thinning['limit']}): "
            "its choices, modes and uncertainties are those rows'; every row was screened and measured"
        )
    if closed["closed"] is False and not screened.selection.gp_added:
        where = gp_section["depends_on"] if gp_section else []
        in_joints = (gp_section or {}).get("joint_error_form") or {}
        warnings.append(
            "no candidate effect explains what is left"
            + (f"; it depends on {', '.join(where)} (residual GP relevance)" if where else "")
            + (
                f"; read as joint-angle errors it lives in {', '.join(in_joints['named_joints'])}"
                if in_joints.get("preferred") == "joint_error" and in_joints.get("named_joints")
                else ""
            )
        )
    warnings += gross_warnings(screened.flagged, screened.screens, screened.settled, screened.history)
    departed = departed_warning(screened.selection)
    if departed:
        warnings.append(departed)
    warnings += symptom_warnings(screened.selection)
    bounded = ((gp_section or {}).get("hyperparameters") or {}).get("at_bounds")
    if bounded:
        warnings.append(
            f"the residual GP's hyperparameters ended on the bounds of their search ({', '.join(bounded)}): "
            "there the data did not determine them, and the GP "
            + ("added is" if gp_section["added"] else "tried was")
            + " what those bounds make it (a signal at its lower bound is no structure found, not a GP of zero signal)"
        )
    if mcmc is not None and not mcmc["converged"]:
        warnings.append(
            f"the MCMC refit did not meet R-hat <= {mcmc['criteria']['max_rhat']} and ESS >= "
            f"{mcmc['criteria']['min_ess']} after {len(mcmc['attempts'])} runs (last: R-hat "
            f"{mcmc['max_rhat']:.3f}, ESS {mcmc['min_ess']:.0f}): its stds are less reliable"
        )
    return warnings


def symptom_warnings(selection: Selection) -> list[str]:
    """One warning per candidate effect refused as a symptom in the selection's rounds
    (`scoring.beyond_prior`): its estimate far beyond its physical prior, it imitated something
    else in the data, which stays unexplained by it."""
    seen = {}
    for entry in selection.rounds:
        for name, scores in (entry.get("scores") or {}).items():
            far = scores.get("beyond_prior") if isinstance(scores, dict) else None
            if far and far.get("prior_stds", 0.0) > evidence.PRIOR_RANGE and name not in seen:
                seen[name] = f"candidate {name} refused in round {entry['round']}: {symptom_text(far)}"
    return list(seen.values())


def departed_warning(selection: Selection) -> str | None:
    """The warning of cross-validation folds whose fit departed (`evidence.DEPARTED_RATIO`,
    `evidence.PRIOR_RANGE`): which folds, in which scores, left out of those decisions; None when
    none departed."""
    where = {}
    if selection.base.cv.departed is not None and selection.base.cv.departed.any():
        where["the zero-offset model"] = np.flatnonzero(selection.base.cv.departed).tolist()
    for r in selection.rounds:
        for name, scores in (r.get("scores") or {}).items():
            if scores.get("cv_departed_folds"):
                where[f"{name} (round {r['round']})"] = scores["cv_departed_folds"]
    if not where:
        return None
    listed = "; ".join(f"{name}: fold {', '.join(str(f + 1) for f in folds)}" for name, folds in where.items())
    return (
        f"cross-validation folds whose fit departed (held-out RMS per axis above {evidence.DEPARTED_RATIO:g} x "
        f"the fit's sigma, or a parameter moved beyond {evidence.PRIOR_RANGE:g} prior standard deviations, "
        f"after iterating the fold's fit): {listed}; each was left out of its "
        "decision, the others decide (the data leave a combination almost free without it)"
    )


def _data_warnings(sensor: SensorData, screened: Screened, between: dict, settings: LoopSettings) -> list[str]:
    """The report's warnings on what the data lack: too few rows for the jackknife and the
    candidates (`jackknife.too_few_warning`), jackknife groups whose refit departed
    (`jackknife.departed_groups_warning`), and a drift candidate left out because its time or
    temperature column has rows without a value (never silently)."""
    data, poses = screened.fitted, screened.fitted_poses
    too_few = too_few_warning(between, len(data.rows), len(np.unique(poses)), not screened.selection.added)
    warnings = [w for w in (too_few, departed_groups_warning(between)) if w]
    if "drift" in settings.candidates and data.drift_gaps:
        warnings.append(
            f"drift not offered: {sensor.name}.parquet: {data.drift_gaps}: a drift is a rate over that column, so "
            "every row needs a value; fill them in for the loop closure to test a drift"
        )
    return warnings


def _noise_model(selection: Selection, sensor: SensorData, settings: LoopSettings, frame_problem) -> dict:
    """loop_closure.json's `noise_model`: the one chosen, or why a tracker's was not offered."""
    return selection.noise or {
        "offered": False,
        "chosen": "isotropic",
        "why": (
            "not a laser tracker"
            if sensor.kind != "laser_tracker"
            else "tracker_noise disabled in the config"
            if settings.tracker_noise is None
            else frame_problem
        ),
    }


def _selection_fields(selection: Selection) -> dict:
    """loop_closure.json's fields of the selection: the effects added, the share of the residual
    each explained when added, every candidate's scores and the rounds."""
    return {
        "effects_added": tuple(selection.added),
        "explained_fraction_when_added": {
            r["added"]: r["scores"][r["added"]]["explained_fraction"]
            for r in selection.rounds
            if r["added"] and r["added"] in selection.added
        },
        "candidates": _per_candidate(selection.rounds),
        "rounds": tuple(
            {"round": r["round"], "model": r["model"], "added": r["added"], **_backward(r)} for r in selection.rounds
        ),
    }


def _refit_fields(final, mcmc, before_table: pd.DataFrame, after_table: pd.DataFrame) -> dict:
    """loop_closure.json's fields of the final model and its refit: its identifiability, the
    parameters the data barely moved from their prior, the refit (the final model's mode, the
    MCMC refit, the parameter table) and how far each zero-offset moved."""
    return {
        "identifiability": final.reduction.report(),
        "prior_dominated": tuple(after_table[after_table["prior_dominated"]]["parameter"].tolist()),
        "refit": {
            "mode": {
                "names": list(final.model.names),
                "theta": final.theta.tolist(),
                "std": final.mode.std.tolist(),
                "sigma_mm": final.mode.sigma / MM,
                "log_evidence": final.mode.log_evidence,
                "bic": final.mode.bic(),
            },
            "mcmc": mcmc,
            "parameters": after_table.replace({np.nan: None}).to_dict(orient="records"),
        },
        "zero_offset_shifts": tuple(zero_offset_shifts(before_table, after_table)),
    }


def _accuracies(screened: Screened) -> tuple[dict, dict, dict, dict]:
    """(before, predicted, after, kept): each set's accuracy measures with the zero-offset model and
    the selected one, without the rows flagged as gross errors, the selected model's predictions
    (m), and, for a set with flagged rows, both measures with them ({set: {'before', 'after'}})."""
    selection, data, poses = screened.selection, screened.data, screened.poses
    every, every_poses = screened.every, screened.every_poses
    before = {s: selection.base.accuracy(data[s], poses[s]) for s in SETS}
    predicted = {s: selection.prediction(data[s]) for s in SETS}
    after = {s: accuracy(data[s].measured, predicted[s], poses[s]) for s in SETS}
    kept = {
        s: {
            "before": selection.base.accuracy(every[s], every_poses[s]),
            "after": accuracy(every[s].measured, selection.prediction(every[s]), every_poses[s]),
        }
        for s in SETS
        if len(screened.flagged[s])
    }
    return before, predicted, after, kept


EVIDENCE = (
    "Laplace log evidence under the extension priors (nats), gain = log Z(with the candidate) - "
    "log Z(current model); pose-grouped K-fold cross-validation on the optimization set; BIC "
    "gain for reference. The validation set is not used to select."
)


def _link_priors(
    chain: KinematicChain, sensor: SensorData, t_nr, base_held, settings: LoopSettings, exclude
) -> tuple[LoopSettings, dict]:
    """The settings with the link geometry's prior at the scale its evidence chooses on the
    optimization set (`link_priors.link_prior_scale`; the provisional gross errors left out), and
    loop_closure.json's `link_prior_scale` (the scale and each scale's log evidence)."""
    if "link_geometry" not in settings.candidates:
        return settings, {"scale": 1.0, "log_evidence": {}, "why": "link_geometry not offered"}
    every = readings(chain, sensor, "optimization", settings.model, exclude)
    data = fitted_rows(every, sensor.table.loc[every.rows, "pose"].to_numpy(), settings.fit_rows)[0]
    scale, at = link_prior_scale(chain, data, sensor.marker, t_nr, base_held, settings.priors)
    chosen = replace(settings, priors=scaled_priors(settings.priors, scale))
    why = (
        "the scale with the highest evidence"
        if at
        else "the link geometry model is not determined: the configured priors"
    )
    return chosen, {"scale": scale, "log_evidence": at, "why": why}


def _settings_report(settings: LoopSettings, chain: KinematicChain, link_scale: dict, thinning: dict) -> dict:
    """loop_closure.json's settings: the loop's, which payload the compliance's torques assume (the
    configured one, or a URDF's own tool), the link geometry's prior scale (`_link_priors`) and the
    optimization rows fitted (`fitted_rows`)."""
    return {
        **settings.report(),
        "payload_assumed": settings.model.payload(chain).report(),
        "link_prior_scale": link_scale,
        "fitted_rows": thinning,
    }


def close_loop(
    chain: KinematicChain,
    sensor: SensorData,
    t_nr,
    base_held: Mapping[str, float],
    rng: np.random.Generator,
    settings: LoopSettings,
    exclude=(),
) -> LoopClosure:
    """Diagnose, decide and refit on the optimization set, then report before and after on both
    sets. t_nr (4, 4): the fit's initial registration; base_held: the zero-offset fit's held
    parameters (identifiability analysis); exclude: table rows the zero-offset model's
    screen left out as gross errors: the first fit leaves them out, then every row of both sets is
    screened with the final model (`remaster.loop.gross`) and the loop refitted without the rows it
    finds until they are the ones it was fitted without; rng feeds the MCMC refit only."""
    settings, link_scale = _link_priors(chain, sensor, t_nr, base_held, settings, exclude)
    screened = select_screened(chain, sensor, t_nr, base_held, settings, exclude)
    selection, data, flagged = screened.selection, screened.data, screened.flagged
    base, final = selection.base, selection.final
    samples, mcmc = None, None
    if settings.mcmc is not None:
        chains, mcmc = refit(final.mode, settings, rng)
        samples = samples_frame(chains)
    before_table = parameter_table(base)
    after_table = parameter_table(final, samples)
    sigma_before = base.mode.sigma
    sigma_after = float(after_table.set_index("parameter").loc[SIGMA, "mean"])
    # the validation set is read here, after every choice has been made
    before, predicted, after, kept = _accuracies(screened)
    fitted = screened.fitted
    closed = closure_report(
        selection,
        fitted,
        sensor.noise,
        settings.closure_level,
        sensor.point_std(fitted.rows),
    )
    gp_section = _residual_section(selection, chain, fitted, sensor.marker, t_nr, settings)
    joint_field = _joint_field(gp_section, selection, chain, fitted, sensor.marker, t_nr)
    between, model_share = _zero_offset_spreads(screened, closed["closed"], settings, gp_section, joint_field)
    screen = (screened.screens, screened.provisional, screened.history, screened.settled)
    report = LoopReport(
        sensor=sensor.name,
        evidence=EVIDENCE,
        selection_data="optimization set only",
        settings=_settings_report(settings, chain, link_scale, screened.thinning),
        **_selection_fields(selection),
        validation_rmse_before_mm=before["validation"]["rmse_mm"],
        validation_rmse_after_mm=after["validation"]["rmse_mm"],
        sigma_before_mm=sigma_before / MM,
        sigma_after_mm=sigma_after / MM,
        before=before,
        after=after,
        **_refit_fields(final, mcmc, before_table, after_table),
        warnings=tuple(
            _warnings(closed, screened, gp_section, mcmc, settings)
            + _data_warnings(sensor, screened, between, settings)
            + not_computed_warning(model_share, closed["closed"], selection.gp_added)
        ),
        closure={k: v for k, v in closed.items() if k != "warnings"},
        residual_gp=gp_section,
        noise_model=_noise_model(selection, sensor, settings, screened.frame_problem),
        gross_errors=gross_report(flagged, *screen, kept, settings.gross_errors),
        between_design=between,
        model_error_share=model_share,
        harmonics=harmonics_report(final.mode, final.reduction, fitted.q, settings.harmonic_level, samples)
        if harmonics.BLOCK in selection.added
        else None,
    )
    counts = (len(base.model.names) + 1, len(final.model.names) + 1)
    table = before_after_table(before, after, sigma_before, sigma_after, counts, kept, flagged)
    residuals = {
        "before": {s: base.residuals(data[s]) for s in SETS},
        "after": {s: data[s].measured - predicted[s] for s in SETS},
    }
    gp = loop_candidate.training_frame(selection.gp) if selection.gp is not None else pd.DataFrame()
    return LoopClosure(report, table, selection.signatures, residuals, samples, gp, {s: data[s].rows for s in SETS})


def _backward(r: dict) -> dict:
    """A backward round's pass and removed block, for loop_closure.json's rounds."""
    if r.get("pass") != "backward":
        return {}
    return {"pass": "backward", "removed": r["removed"], **({"with": r["with"]} if "with" in r else {})}


def _per_candidate(rounds: list[dict]) -> dict[str, list[dict]]:
    """{candidate: [its scores in each round it was tried, with the round number]}."""
    out: dict[str, list[dict]] = {}
    for r in rounds:
        for name, scores in r["scores"].items():
            out.setdefault(name, []).append({"round": r["round"], **scores})
    return out


def loop_closure_stage(
    campaign: Campaign,
    sensor: str,
    registration: fit.Registration,
    laplace: LaplaceReport,
    rng: np.random.Generator,
    settings: LoopSettings,
) -> LoopClosure:
    """Loop closure of one sensor of a campaign after its zero-offset fit (the registration and
    Laplace reports of `fit`). The campaign's `robot.priors` override the settings' priors, and its
    `robot.joint_encoders` chooses the joint scale's."""
    if campaign.robot.get("priors") or campaign.robot.get("joint_encoders"):
        settings = replace(
            settings, priors=priors_from(settings.priors_config, campaign.robot, f"{campaign.name}/campaign.yaml")
        )
    result = close_loop(
        campaign.chain,
        campaign.sensors[sensor],
        registration.t_nr,
        laplace.held_with_points_alone,  # the loop's models are of the positions
        rng,
        settings,
        laplace.outlier_rows,
    )
    return replace(result, report=replace(result.report, campaign=campaign.name))
