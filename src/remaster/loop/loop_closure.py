"""Loop closure: what the zero-offset model leaves in the residuals, named and removed.

Per campaign and sensor, after the zero-offset fit, on the OPTIMIZATION set only:

1. Diagnose: for each candidate block (`blocks.EXTENSIONS`; drift only when the table has a
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
   parametric effect passes, a laser tracker's noise is offered as it is, range and transverse
   growing with distance (`remaster.noise`), against the isotropic noise by the same evidence
   threshold; then the residual Gaussian process over the joints (`remaster.inference.residual_gp`)
   is tried last by the same two tests; fitted or not, it says which joints what is left depends on.
   After every step the closure test (`remaster.loop.closure`) compares the cross-validated residual
   with the sensor's noise and says what share of the structured residual the step removed.
3. Refit the final model by MCMC (independence Metropolis from the Laplace approximation, run
   longer until it meets the project's convergence criteria, or reported as not converged) so
   that every parameter carries uncertainty; say which parameters the data barely moved from
   their prior.
4. Only then the VALIDATION set: accuracy before (zero-offset model) and after (the selected
   model), each with the optimization fit's parameters and registration. Nothing is selected,
   tuned or stopped on it.

Accuracy measures (per set, in mm): post-registration RMSE sqrt(mean |E_i|^2) over the points,
the RMS per axis (comparable to sigma and the sensor noise), the paper's mean post-registration
error mean |E_i|, and the paper's relative error |d(ref) - d(model)| over the pairs of
configurations of each pose (`remaster.inference.metrics`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

from .. import noise
from ..campaigns.campaign import Campaign, SensorData
from ..inference import blocks, evidence, fit, gauge, metrics, residual_gp, samplers
from ..inference.blocks import BlockModel, ModelSettings, Readings, Reduction
from ..inference.model import SIGMA
from ..robot.kinematics import KinematicChain
from ..robot.priors import DEFAULTS as DEFAULT_PRIORS, Priors, priors_from, with_defaults
from ..units import DEG, MM
from . import closure

SETS = ("optimization", "validation")
MCMC_DEFAULT = {"chains": 2, "samples": 2000, "burn_in": 500}
# The refit's Student-t proposal: a t in P dimensions is a Gaussian whose scale varies by a factor
# sqrt(chi2_dof / dof) shared by all P coordinates, so with few degrees of freedom most draws land
# at the wrong radius (log-weights spread by ~P / sqrt(2 dof) nats); dof ~ 4 P keeps that spread
# near 1 nat and the tails still heavier than a Gaussian posterior's.
PROPOSAL_DOF_PER_PARAMETER = 4
PROPOSAL_INFLATION = 1.1
CONVERGENCE_DEFAULT = {"max_rhat": 1.05, "min_ess": 200.0, "max_doublings": 4}
GP_DEFAULT = {"subset": residual_gp.SUBSET, "inducing": residual_gp.INDUCING}
GP = "residual_gp"
TRACKER_NOISE_DEFAULT = {"growth_per_m": noise.GROWTH_PRIOR_PER_M,
                         "growth_factor": math.exp(noise.GROWTH_PRIOR_LOG_STD)}
NOISE_SEARCH_WIDTH = 3.0  # prior stds of log g either side of its median searched for the mode
MIN_GP_POSES = 10  # fewer poses than this cannot tell a smooth residual from noise
# posterior std / prior std above this: the data barely moved the parameter from its prior
PRIOR_DOMINATED = 0.5


@dataclass(frozen=True)
class LoopSettings:
    """candidates: extension blocks to try; min_log_evidence_gain: the Laplace evidence (nats) an
    effect needs; cv_folds, cv_standard_errors: the pose-grouped cross-validation and the number
    of its standard errors the fall must exceed; model: payload and drift column; priors: the
    extension blocks' Gaussian priors; mcmc: {'chains', 'samples', 'burn_in'} of the final
    refit's first attempt, None for Laplace only; priors_config: the config's `priors` section, which
    a campaign's own `robot.priors` is laid over; convergence: {'max_rhat', 'min_ess',
    'max_doublings'}: the refit's run length doubles until they hold, at most max_doublings times;
    residual_gp: {'subset', 'inducing'} of the Gaussian-process candidate tried last
    (`remaster.inference.residual_gp`), None not to try it; closure_ratio: the RMS per axis over the noise
    floor at which the loop counts as closed (`remaster.loop.closure`); tracker_noise: {'growth_per_m',
    'growth_factor'}, the log-normal prior of a laser tracker's range/transverse noise model
    (`remaster.noise`), None not to offer it."""

    candidates: tuple[str, ...] = blocks.EXTENSIONS
    min_log_evidence_gain: float = 5.0
    cv_folds: int = 5
    cv_standard_errors: float = 2.0
    model: ModelSettings = ModelSettings()
    priors: Priors = field(default_factory=lambda: priors_from(DEFAULT_PRIORS))
    priors_config: dict = field(default_factory=lambda: dict(DEFAULT_PRIORS))
    mcmc: dict | None = field(default_factory=lambda: dict(MCMC_DEFAULT))
    convergence: dict = field(default_factory=lambda: dict(CONVERGENCE_DEFAULT))
    residual_gp: dict | None = field(default_factory=lambda: dict(GP_DEFAULT))
    closure_ratio: float = closure.CLOSURE_RATIO
    tracker_noise: dict | None = field(default_factory=lambda: dict(TRACKER_NOISE_DEFAULT))

    def report(self) -> dict:
        return {"candidates": list(self.candidates), "min_log_evidence_gain": self.min_log_evidence_gain,
                "cv_folds": self.cv_folds, "cv_standard_errors": self.cv_standard_errors,
                "payload_mass_kg": self.model.payload_mass, "payload_com_m": list(self.model.payload_com),
                "drift_column": self.model.drift_column, "priors": self.priors.report(), "mcmc": self.mcmc,
                "convergence": self.convergence, "residual_gp": self.residual_gp, "closure_ratio": self.closure_ratio,
                "tracker_noise": self.tracker_noise}


# --------------------------------------------------------------------------- accuracy measures


def accuracy(measured, predicted, poses) -> dict:
    """Post-registration and relative accuracy (mm) of predictions (n, 3) against measurements
    (n, 3), both in the sensor frame; poses (n,) group the relative measure's pairs
    (`remaster.inference.metrics`)."""
    error = np.asarray(measured) - np.asarray(predicted)
    norms = metrics.post_registration_errors(measured, predicted)
    relative = metrics.interval_summary(metrics.relative_errors(measured, predicted, poses))
    return {"points": int(len(norms)), "rmse_mm": float(np.sqrt(np.mean(norms**2)) / MM),
            "rms_per_axis_mm": float(np.sqrt(np.mean(error**2)) / MM), "mean_error_mm": float(norms.mean() / MM),
            "error_q97.5_mm": float(np.quantile(norms, 0.975) / MM), "relative_pairs": relative["count"],
            "relative_mean_mm": relative["mean"] / MM if relative["count"] else None}


# --------------------------------------------------------------------------- one fit


@dataclass(frozen=True, eq=False)
class Fitted:
    """One model at its posterior mode on the optimization set, with its pose-grouped
    cross-validation and the identifiability reduction of its extensions."""

    mode: evidence.PosteriorMode
    reduction: Reduction
    cv: evidence.CrossValidation

    @property
    def model(self) -> BlockModel:
        return self.mode.model

    @property
    def theta(self) -> np.ndarray:
        return self.mode.theta

    def values(self) -> dict[str, float]:
        return self.model.values(self.theta)

    def residuals(self, data: Readings | None = None) -> np.ndarray:
        """(n, 3) measured - predicted, m, on the optimization set or other readings, with the
        optimization fit's parameters and registration."""
        return (self.model if data is None else self.model.on(data)).residuals(self.theta)

    def accuracy(self, data: Readings, poses) -> dict:
        """`accuracy` on some readings (n rows) with the optimization fit's parameters; poses (n,)."""
        model = self.model.on(data)
        return accuracy(model.measured, model.predict(self.theta), poses)


def fit_blocks(chain: KinematicChain, data: Readings, marker, t_nr, extensions: Sequence[str],
               base_held: Mapping[str, float], folds: np.ndarray, priors: Priors,
               start: Mapping[str, float] | None = None) -> Fitted:
    """Base + extensions under their priors on the optimization readings, from `start`
    ({name: value}; 0 for the others), with its cross-validation over `folds` (n,)."""
    model, reduction = blocks.extended_model(chain, data, marker, t_nr, extensions, base_held, priors)
    mode = evidence.posterior_mode(model, model.vector(start or {}))
    return Fitted(mode, reduction, evidence.cross_validate(mode, folds))


# --------------------------------------------------------------------------- diagnose and decide


@dataclass(frozen=True, eq=False)
class Signature:
    """What a candidate would explain: residual (n, 3) m of the current fit on the optimization
    set, effect (n, 3) m the change in the prediction the candidate's fit makes; when the
    candidate is the missing effect, effect ~ residual. residual - effect is the candidate's
    residual, so `explained` is the fraction of the sum of squares it removes."""

    residual: np.ndarray
    effect: np.ndarray

    @property
    def explained(self) -> float:
        """1 - |residual - effect|^2 / |residual|^2."""
        return float(1.0 - np.sum((self.residual - self.effect) ** 2) / np.sum(self.residual**2))


def score(current: Fitted, candidate: Fitted, settings: LoopSettings) -> dict:
    """A candidate's scores against the current fit (JSON-ready), and whether it passes."""
    out = {"log_evidence_gain": candidate.mode.log_evidence - current.mode.log_evidence,
           "bic_gain": current.mode.bic() - candidate.mode.bic(),
           **evidence.cv_gain(current.cv, candidate.cv),
           "sigma_mm": candidate.mode.sigma / MM, "parameters": list(candidate.reduction.kept),
           "dropped": dict(candidate.reduction.dropped), "weak": dict(candidate.reduction.weak),
           "condition_number": candidate.reduction.condition_number}
    out["passed"] = bool(out["log_evidence_gain"] > settings.min_log_evidence_gain
                         and out["cv_mse_fall_in_se"] > settings.cv_standard_errors)
    return out


@dataclass(frozen=True, eq=False)
class Selection:
    """The greedy forward selection: final fit (parametric), the base fit, the rounds (JSON-ready)
    and the signatures {round: {candidate: Signature}}; gp: the Gaussian process fitted to what the
    parametric effects left (added or not: it also says where the residual lives), None when not
    tried; rotation (3, 3): the final fit's registration (robot -> sensor), which the GP's robot-frame
    correction goes through."""

    base: Fitted
    final: Fitted
    added: tuple[str, ...]
    rounds: list[dict]
    signatures: dict[int, dict[str, Signature]]
    gp: residual_gp.Candidate | None = None
    rotation: np.ndarray | None = None
    noise: dict | None = None

    @property
    def gp_added(self) -> bool:
        return GP in self.added

    def prediction(self, data: Readings) -> np.ndarray:
        """(n, 3) m predicted sensor-frame positions of the selected model (parametric fit at its
        mode, plus the GP's mean when it was added) at some readings."""
        predicted = self.final.model.on(data).predict(self.final.theta)
        return predicted + self.gp.gp.mean(data.q) @ self.rotation.T if self.gp_added else predicted


def select(chain: KinematicChain, data: Readings, marker, t_nr, base_held: Mapping[str, float], poses,
           settings: LoopSettings, tracker: bool = False) -> Selection:
    """Diagnose and decide (module docstring, steps 1 and 2) on the optimization readings;
    poses (n,) their pose labels, which make the cross-validation folds; tracker: whether the
    sensor is a laser tracker, whose range/transverse noise is then offered."""
    folds = evidence.pose_folds(poses, settings.cv_folds)
    base = current = fit_blocks(chain, data, marker, t_nr, (), base_held, folds, settings.priors)
    remaining = [c for c in settings.candidates if blocks.available(c, data)]
    added: list[str] = []
    rounds, signatures = [], {}
    while remaining:
        number = len(rounds) + 1
        residual, prediction = current.residuals(), current.model.predict(current.theta)
        scores, fits, signatures[number] = {}, {}, {}
        for candidate in remaining:
            try:
                fitted = fit_blocks(chain, data, marker, t_nr, tuple(added) + (candidate,), base_held, folds,
                                    settings.priors, current.values())
            except np.linalg.LinAlgError as exc:
                scores[candidate] = {"skipped": f"not identifiable: {exc}"}
                continue
            if not fitted.reduction.kept:
                scores[candidate] = {"skipped": "no parameter of this block is visible in these data",
                                     "dropped": dict(fitted.reduction.dropped)}
                continue
            fits[candidate] = fitted
            signature = signatures[number][candidate] = Signature(residual,
                                                                  fitted.model.predict(fitted.theta) - prediction)
            scores[candidate] = {**score(current, fitted, settings), "explained_fraction": signature.explained}
        passing = [c for c in fits if scores[c]["passed"]]
        best = max(passing, key=lambda c: scores[c]["log_evidence_gain"]) if passing else None
        rounds.append({"round": number, "model": list(blocks.BASE) + added, "scores": scores, "added": best})
        if best is None:
            break
        current = fits[best]
        added.append(best)
        remaining.remove(best)
    noise_choice = None
    if tracker and settings.tracker_noise is not None:
        current, noise_choice = choose_noise(current, folds, settings)
    rotation = current.model.sensor_rotation(current.theta)
    if settings.residual_gp is None or len(np.unique(poses)) < MIN_GP_POSES:
        return Selection(base, current, tuple(added), rounds, signatures, None, rotation, noise_choice)
    gp, scores = _score_gp(current, data, rotation, folds, settings)
    if rounds and rounds[-1]["added"] is None:  # tried in the round where no parametric effect passed
        last = rounds[-1]
    else:
        last = {"round": len(rounds) + 1, "model": list(blocks.BASE) + added, "scores": {}, "added": None}
        rounds.append(last)
    last["scores"][GP] = scores
    if scores["passed"]:
        last["added"] = GP
        added.append(GP)
    return Selection(base, current, tuple(added), rounds, signatures, gp, rotation, noise_choice)


def choose_noise(current: Fitted, folds: np.ndarray, settings: LoopSettings) -> tuple[Fitted, dict]:
    """The current model with a laser tracker's range/transverse noise (`remaster.noise`) against
    its isotropic noise: g at the mode of log Z(g) + log prior(g), the model's evidence with g
    integrated by a Laplace step in log g; taken when it gains `min_log_evidence_gain`. Returns
    the chosen fit and a JSON-ready report."""
    import scipy.optimize
    prior = settings.tracker_noise
    median, log_std = float(prior["growth_per_m"]), math.log(float(prior["growth_factor"]))

    def mode_at(log_growth: float) -> evidence.PosteriorMode:
        return evidence.posterior_mode(current.model.with_noise(noise.RangeTransverse(math.exp(log_growth))),
                                       current.theta)

    def objective(log_growth: float) -> float:
        return -(mode_at(log_growth).log_evidence + noise.log_growth_prior(log_growth, median, log_std))

    centre, width = math.log(median), NOISE_SEARCH_WIDTH * log_std
    best = scipy.optimize.minimize_scalar(objective, bounds=(centre - width, centre + width), method="bounded",
                                          options={"xatol": 0.05})
    step = 0.1  # in log g: the posterior of log g is wider than this wherever the data leave g free
    curvature = (objective(best.x + step) - 2.0 * best.fun + objective(best.x - step)) / step**2
    curvature = max(curvature, 1.0 / log_std**2)  # the prior alone curves this much; a noisy difference may not
    log_evidence = -best.fun + 0.5 * math.log(2.0 * math.pi) - 0.5 * math.log(curvature)
    gain = log_evidence - current.mode.log_evidence
    mode = mode_at(best.x)
    growth = math.exp(best.x)
    distance = np.linalg.norm(current.model.measured, axis=1)
    chosen = bool(gain > settings.min_log_evidence_gain)
    report = {"offered": True, "compared": "range/transverse (laser tracker) against isotropic",
              **noise.RangeTransverse(growth).report(),
              "prior": {"growth_per_m_median": median, "growth_factor": float(prior["growth_factor"])},
              "growth_std_log": 1.0 / math.sqrt(curvature), "log_evidence_isotropic": current.mode.log_evidence,
              "log_evidence_range_transverse": float(log_evidence), "log_evidence_gain": float(gain),
              "sigma_isotropic_mm": current.mode.sigma / MM, "sigma_range_mm": mode.sigma / MM,
              "sigma_transverse_at_median_distance_mm": mode.sigma * math.sqrt(1.0 + (growth * float(
                  np.median(distance))) ** 2) / MM, "median_distance_m": float(np.median(distance)),
              "chosen": "range_transverse" if chosen else "isotropic",
              "note": "sigma of the chosen range/transverse model is the range std; the transverse std grows with "
                      "the distance from the sensor frame's origin, which must be the tracker head"}
    if not chosen:
        return current, report
    return Fitted(mode, current.reduction, evidence.cross_validate(mode, folds)), report


def _score_gp(current: Fitted, data: Readings, rotation: np.ndarray, folds: np.ndarray, settings: LoopSettings
              ) -> tuple[residual_gp.Candidate, dict]:
    """The Gaussian process on the current fit's residuals (robot frame) and its scores by the
    parametric candidates' rule: evidence gain and pose-grouped cross-validated fall."""
    residual = current.residuals()
    gp = residual_gp.candidate(data.q, residual @ rotation, current.cv.held_out @ rotation, folds,
                               int(settings.residual_gp["subset"]), int(settings.residual_gp["inducing"]))
    signature = Signature(residual, gp.gp.mean(data.q) @ rotation.T)
    scores = {"log_evidence_gain": gp.log_evidence_gain,
              **evidence.cv_gain(current.cv, evidence.CrossValidation(gp.mse, gp.points)),
              "sigma_mm": gp.gp.hyper.noise_std / MM, "parameters": ["lengthscales", "signal_std", "noise_std"],
              "explained_fraction": signature.explained}
    scores["passed"] = bool(scores["log_evidence_gain"] > settings.min_log_evidence_gain
                            and scores["cv_mse_fall_in_se"] > settings.cv_standard_errors)
    return gp, scores


# --------------------------------------------------------------------------- the MCMC refit


def refit(mode: evidence.PosteriorMode, settings: LoopSettings, rng: np.random.Generator
          ) -> tuple[list[samplers.Chain], dict]:
    """Chains of the model's posterior by independence Metropolis from its Laplace approximation
    (`samplers.metropolis_independence`), in the coordinates where that approximation fits best
    (`gauge.sampling_coordinates`: the model's exact symmetries folded out), run longer (samples
    and burn-in doubled) until every R-hat <= max_rhat and every ESS >= min_ess, at most
    max_doublings times. Returns the chains, in the model's own parameters, and a JSON-ready
    report: the last run's diagnostics, every attempt, the coordinates, and `converged`."""
    target = fit.PosteriorTarget(mode.model)
    mean = np.append(mode.theta, mode.sigma)
    covariance = mode.covariance
    # the model's exact symmetries are curved ridges in its own parameters, straight in folded ones
    target, mean, covariance, folds, coordinates = gauge.sampling_coordinates(target, mode.model, mean, covariance,
                                                                               rng)
    run, criteria = dict(settings.mcmc), settings.convergence
    attempts = []
    for attempt in range(int(criteria["max_doublings"]) + 1):
        started = time.perf_counter()
        chains = samplers.run_chains(samplers.metropolis_independence, target, rng, int(run["chains"]), mean,
                                     mean=mean, covariance=covariance, n_samples=int(run["samples"]),
                                     burn_in=int(run["burn_in"]), dof=PROPOSAL_DOF_PER_PARAMETER * len(mean),
                                     inflation=PROPOSAL_INFLATION)
        if folds is not None:
            chains = [folds.back(c) for c in chains]
        report = fit.sampler_diagnostics(chains, time.perf_counter() - started)
        done = fit.converged(report, criteria["max_rhat"], criteria["min_ess"])
        attempts.append({"samples": int(run["samples"]), "burn_in": int(run["burn_in"]),
                         "max_rhat": report["max_rhat"], "min_ess": report["min_ess"],
                         "acceptance_rate": report["acceptance_rate"], "seconds": report["seconds"],
                         "converged": done})
        if done:
            break
        run = {**run, "samples": 2 * int(run["samples"]), "burn_in": 2 * int(run["burn_in"])}
    return chains, {**report, "converged": done, "attempts": attempts, "coordinates": coordinates,
                    "criteria": {"max_rhat": criteria["max_rhat"], "min_ess": criteria["min_ess"]}}


def parameter_table(fitted: Fitted, samples: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per parameter (held ones included) and sigma: mean, std and 95 % interval in SI and in
    display units, prior std, the posterior / prior std ratio, status, and why the data cannot see
    it (`unseen_by_data`: kept under its prior, or held without one). From the MCMC samples when
    given, else the Laplace approximation (mean = mode, interval mode +- 1.96 std)."""
    model = fitted.model
    names = list(model.names) + [SIGMA]
    if samples is not None:
        summary = fit.moments(samples[names])
        mean, std, low, high = (summary[c].to_numpy() for c in ("mean", "std", "q2.5", "q97.5"))
        source = "MCMC (independence Metropolis)"
    else:
        mean = np.append(fitted.theta, fitted.mode.sigma)
        std = np.append(fitted.mode.std, fitted.mode.sigma_std)
        low, high = mean - metrics.Z95 * std, mean + metrics.Z95 * std
        source = "posterior mode + Laplace"
    free = {n: (m, s, lo, hi) for n, m, s, lo, hi in zip(names, mean, std, low, high)}
    prior = dict(zip(model.names, model.prior_std))
    reasons = {**{n: "held: not identifiable" for n in model.fixed},
               **{n: f"held: {why}" for n, why in fitted.reduction.dropped.items() if n in model.fixed}}
    rows = []
    for name, scale, unit in list(zip(model.all_names, model.all_scale, model.all_unit)) + [(SIGMA, MM, "mm")]:
        m, s, lo, hi = free.get(name, (model.fixed.get(name, 0.0), np.nan, np.nan, np.nan))
        tau = prior.get(name, np.inf)
        ratio = s / tau if np.isfinite(tau) and np.isfinite(s) else np.nan
        rows.append({"parameter": name, "block": model.block_of.get(name, "noise"), "mean": m, "std": s,
                     "q2.5": lo, "q97.5": hi, "unit": unit, "mean_display": m / scale, "std_display": s / scale,
                     "q2.5_display": lo / scale, "q97.5_display": hi / scale,
                     "prior_std_display": tau / scale if np.isfinite(tau) else np.nan,
                     "posterior_to_prior_std": ratio, "prior_dominated": bool(ratio > PRIOR_DOMINATED),
                     "status": "estimated" if name in free else reasons.get(name, "held"),
                     "unseen_by_data": fitted.reduction.dropped.get(name, ""), "source": source})
    return pd.DataFrame(rows)


def zero_offset_shifts(before: pd.DataFrame, after: pd.DataFrame) -> list[dict]:
    """How far each zero-offset moved (deg) and in units of its std before and after."""
    before, after = before.set_index("parameter"), after.set_index("parameter")
    out = []
    for name in [n for n in after.index if n.startswith("zero_offsets.")]:
        first, last = float(before.loc[name, "mean"]) / DEG, float(after.loc[name, "mean"]) / DEG
        row = {"parameter": name, "before_deg": first, "after_deg": last, "shift_deg": last - first,
               "std_before_deg": None, "std_after_deg": None, "shift_in_std_before": None, "shift_in_std_after": None}
        if after.loc[name, "status"] == "estimated":
            row["std_before_deg"] = float(before.loc[name, "std"]) / DEG
            row["std_after_deg"] = float(after.loc[name, "std"]) / DEG
            row["shift_in_std_before"] = (last - first) / row["std_before_deg"]
            row["shift_in_std_after"] = (last - first) / row["std_after_deg"]
        out.append(row)
    return out


def before_after_table(before: dict, after: dict, sigma_before: float, sigma_after: float,
                       parameters: tuple[int, int]) -> pd.DataFrame:
    """The report's table: accuracy on both sets, sigma and parameter count, before (zero-offset
    model) and after (with the effects added)."""
    rows = [("sigma (mm)", sigma_before / MM, sigma_after / MM),
            ("free parameters", parameters[0], parameters[1])]
    for set_name in SETS:
        for key, label in (("rmse_mm", "post-registration RMSE (mm)"), ("rms_per_axis_mm", "RMS per axis (mm)"),
                           ("mean_error_mm", "mean post-registration error (mm)"),
                           ("relative_mean_mm", "mean relative error (mm)")):
            rows.append((f"{set_name}: {label}", before[set_name][key], after[set_name][key]))
    return pd.DataFrame(rows, columns=["Quantity", "Before (zero-offsets)", "After (with effects)"])


@dataclass(frozen=True, eq=False)
class LoopClosure:
    """report: JSON-ready; table: before/after; signatures: {round: {candidate: Signature}};
    residuals: {'before'|'after': {set: (n, 3) m}}; samples: the MCMC refit (SI) or None;
    gp: the residual GP's training rows when it was tried (`residual_gp.training_frame`), else an
    empty frame; rows: {set: (n,) the sensor table's row of each residual}."""

    report: dict
    table: pd.DataFrame
    signatures: dict[int, dict[str, Signature]]
    residuals: dict[str, dict[str, np.ndarray]]
    samples: pd.DataFrame | None
    gp: pd.DataFrame = field(default_factory=pd.DataFrame)
    rows: dict[str, np.ndarray] = field(default_factory=dict)


def close_loop(chain: KinematicChain, sensor: SensorData, t_nr, base_held: Mapping[str, float],
               rng: np.random.Generator, settings: LoopSettings = LoopSettings(), exclude=()) -> LoopClosure:
    """Diagnose, decide and refit on the optimization set, then report before and after on both
    sets. t_nr (4, 4): the fit's initial registration; base_held: the zero-offset fit's held
    parameters (identifiability analysis); exclude: table rows the fit left out as gross errors
    (left out here too); rng feeds the MCMC refit only."""
    data = {s: blocks.readings(chain, sensor, s, settings.model, exclude) for s in SETS}
    poses = {s: sensor.table.loc[data[s].rows, "pose"].to_numpy() for s in SETS}
    frame_problem = noise.frame_problem(t_nr, data["optimization"].measured)
    tracker = sensor.kind == "laser_tracker" and settings.tracker_noise is not None and frame_problem is None
    selection = select(chain, data["optimization"], sensor.marker, t_nr, base_held, poses["optimization"], settings,
                       tracker=tracker)
    base, final = selection.base, selection.final

    samples, mcmc = None, None
    if settings.mcmc is not None:
        chains, mcmc = refit(final.mode, settings, rng)
        samples = fit.samples_frame(chains)
    before_table = parameter_table(base)
    after_table = parameter_table(final, samples)
    sigma_before = base.mode.sigma
    sigma_after = float(after_table.set_index("parameter").loc[SIGMA, "mean"])
    # the validation set is read here, after every choice has been made
    before = {s: base.accuracy(data[s], poses[s]) for s in SETS}
    predicted = {s: selection.prediction(data[s]) for s in SETS}
    after = {s: accuracy(data[s].measured, predicted[s], poses[s]) for s in SETS}
    counts = (len(base.model.names) + 1, len(final.model.names) + 1)
    dominated = after_table[after_table["prior_dominated"]]
    explained = {r["added"]: r["scores"][r["added"]]["explained_fraction"] for r in selection.rounds if r["added"]}
    closed = closure_report(selection, data["optimization"], sensor.noise, settings.closure_ratio)
    gp_section = gp_report(selection, settings.cv_standard_errors)
    warnings = list(closed["warnings"])
    if closed["closed"] is False and not selection.gp_added:
        where = gp_section["depends_on"] if gp_section else []
        warnings.append("no candidate effect explains what is left" + (
            f"; it depends on {', '.join(where)} (residual GP relevance)" if where else ""))
    if mcmc is not None and not mcmc["converged"]:
        warnings.append(f"the MCMC refit did not meet R-hat <= {mcmc['criteria']['max_rhat']} and ESS >= "
                        f"{mcmc['criteria']['min_ess']} after {len(mcmc['attempts'])} runs (last: R-hat "
                        f"{mcmc['max_rhat']:.3f}, ESS {mcmc['min_ess']:.0f}): its stds are less reliable")
    report = {
        "sensor": sensor.name,
        "evidence": "Laplace log evidence under the extension priors (nats), gain = log Z(with the candidate) - "
                    "log Z(current model); pose-grouped K-fold cross-validation on the optimization set; BIC "
                    "gain for reference. The validation set is not used to select.",
        "selection_data": "optimization set only",
        "settings": settings.report(),
        "effects_added": list(selection.added),
        "explained_fraction_when_added": explained,
        "candidates": _per_candidate(selection.rounds),
        "rounds": [{"round": r["round"], "model": r["model"], "added": r["added"]} for r in selection.rounds],
        "validation_rmse_before_mm": before["validation"]["rmse_mm"],
        "validation_rmse_after_mm": after["validation"]["rmse_mm"],
        "sigma_before_mm": sigma_before / MM, "sigma_after_mm": sigma_after / MM,
        "before": before, "after": after,
        "identifiability": final.reduction.report(),
        "prior_dominated": dominated["parameter"].tolist(),
        "warnings": warnings,
        "refit": {"mode": {"names": list(final.model.names), "theta": final.theta.tolist(),
                           "std": final.mode.std.tolist(), "sigma_mm": final.mode.sigma / MM,
                           "log_evidence": final.mode.log_evidence, "bic": final.mode.bic()},
                  "mcmc": mcmc,
                  "parameters": after_table.replace({np.nan: None}).to_dict(orient="records")},
        "zero_offset_shifts": zero_offset_shifts(before_table, after_table),
        "closure": {k: v for k, v in closed.items() if k != "warnings"},
        "residual_gp": gp_section,
        "noise_model": selection.noise or {"offered": False, "chosen": "isotropic", "why": (
            "not a laser tracker" if sensor.kind != "laser_tracker" else "tracker_noise disabled in the config"
            if settings.tracker_noise is None else frame_problem)},
    }
    table = before_after_table(before, after, sigma_before, sigma_after, counts)
    residuals = {"before": {s: base.residuals(data[s]) for s in SETS},
                 "after": {s: data[s].measured - predicted[s] for s in SETS}}
    gp = residual_gp.training_frame(selection.gp) if selection.gp is not None else pd.DataFrame()
    return LoopClosure(report, table, selection.signatures, residuals, samples, gp, {s: data[s].rows for s in SETS})


def closure_report(selection: Selection, data: Readings, stated_noise: float | None, ratio: float) -> dict:
    """The closure test after every round (`remaster.loop.closure`) on the optimization readings: the
    noise floor, each round's cross-validated RMS per axis and verdict, each added step's share of
    the structured residual, the final verdict, and the warnings it calls for."""
    repeats, repeated = closure.repeatability(data.q, data.measured)
    floor = closure.noise_floor(stated_noise, repeats)
    steps = [("zero-offsets (paper)", selection.base.cv.rmse / math.sqrt(3.0))]
    for r in selection.rounds:
        if r["added"]:
            steps.append((r["added"], r["scores"][r["added"]]["cv_rmse_mm"] * MM / math.sqrt(3.0)))
    rounds = [{"after": name, **closure.verdict(rms, floor, ratio)} for name, rms in steps]
    shares = {name: closure.share(before, after, floor, ratio) for (_, before), (name, after) in zip(steps, steps[1:])}
    final = rounds[-1]
    warnings = []
    if final["closed"] is False:
        minor = [f"{name} ({100 * value:.0f} %)" for name, value in shares.items()
                 if value is not None and value < closure.MAIN_CAUSE_SHARE]
        warnings.append(f"loop {final['text']}"
                        + (f"; effects added that explain only a small share of what was left, not its cause: "
                           f"{', '.join(minor)}" if minor else ""))
    return {"stated_noise_mm": None if stated_noise is None else stated_noise / MM,
            "repeatability_mm": None if repeats is None else repeats / MM, "repeated_configurations": repeated,
            "noise_floor_mm": None if floor is None else floor / MM, "ratio": ratio,
            "measure": "pose-grouped cross-validated RMS per axis on the optimization set",
            "rounds": rounds, "share_of_structured_residual": shares,
            "main_causes": [n for n, v in shares.items() if v is not None and v >= closure.MAIN_CAUSE_SHARE],
            "closed": final["closed"], "verdict": final["text"], "warnings": warnings}


def gp_report(selection: Selection, standard_errors: float) -> dict | None:
    """Where the residual the parametric effects left lives: the GP's hyperparameters, each joint's
    relevance (measured range / lengthscale), the joints it depends on, and the share of that
    residual which is structured (cross-validated fall of its mean square) vs noise. The joints
    are named only when there is structure to trace: the GP's cross-validated fall exceeds
    `standard_errors` standard errors. None when the GP was not tried."""
    if selection.gp is None:
        return None
    candidate = selection.gp
    relevance = candidate.relevance()
    columns = [f"q{j + 1}" for j in range(len(relevance))]
    order = np.argsort(-relevance)
    fall = evidence.cv_gain(selection.final.cv, evidence.CrossValidation(candidate.mse, candidate.points))
    structured = fall["cv_mse_fall_in_se"] > standard_errors
    before = float(np.sum(selection.final.cv.mse * selection.final.cv.points))
    after = float(np.sum(candidate.mse * candidate.points))
    return {"added": selection.gp_added, "hyperparameters": candidate.gp.hyper.report(),
            "relevance": dict(zip(columns, relevance.tolist())), "structure_found": bool(structured),
            "depends_on": [columns[j] for j in order if structured and relevance[j] >= residual_gp.RELEVANT_RANGE],
            "most_relevant_joint": columns[int(order[0])] if structured else None,
            "structured_fraction": max(0.0, 1.0 - after / before) if before > 0 else 0.0,
            "frame": "robot (the residual rotated back by the final fit's registration)",
            "rows": int(len(candidate.q)), "inducing": int(len(candidate.gp.inducing)),
            "rotation_robot_to_sensor": selection.rotation.tolist()}


def _per_candidate(rounds: list[dict]) -> dict[str, list[dict]]:
    """{candidate: [its scores in each round it was tried, with the round number]}."""
    out: dict[str, list[dict]] = {}
    for r in rounds:
        for name, scores in r["scores"].items():
            out.setdefault(name, []).append({"round": r["round"], **scores})
    return out


def loop_closure_stage(campaign: Campaign, sensor: str, registration: fit.Registration, laplace: fit.LaplaceReport,
                       rng: np.random.Generator, settings: LoopSettings = LoopSettings()) -> LoopClosure:
    """Loop closure of one sensor of a campaign after its zero-offset fit (the registration and
    Laplace reports of `fit`). The campaign's `robot.priors` override the settings' priors."""
    if campaign.robot.get("priors"):
        settings = replace(settings, priors=priors_from(settings.priors_config, campaign.robot,
                                                        f"{campaign.name}/campaign.yaml"))
    result = close_loop(campaign.chain, campaign.sensors[sensor], registration.t_nr, laplace.held, rng,
                        settings, laplace.outlier_rows)
    result.report["campaign"] = campaign.name
    return result


# --------------------------------------------------------------------------- files and tables


def signatures_frame(signatures: dict[int, dict[str, Signature]]) -> pd.DataFrame:
    """Long table of every round's candidate signatures: round, candidate, point, axis, residual_m, effect_m."""
    frames = []
    for round_number, candidates in signatures.items():
        for name, signature in candidates.items():
            n = len(signature.residual)
            frames.append(pd.DataFrame({
                "round": np.int64(round_number), "candidate": name,
                "point": np.repeat(np.arange(n, dtype=np.int64), 3), "axis": np.tile(["x", "y", "z"], n),
                "residual_m": signature.residual.ravel(), "effect_m": signature.effect.ravel()}))
    columns = ["round", "candidate", "point", "axis", "residual_m", "effect_m"]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)


def signatures_of_round(frame: pd.DataFrame, round_number: int = 1) -> dict[str, Signature]:
    """The candidates' signatures of one round back from `signatures_frame`."""
    out = {}
    for name, part in frame[frame["round"] == round_number].groupby("candidate", sort=False):
        part = part.sort_values(["point", "axis"])
        out[name] = Signature(part["residual_m"].to_numpy().reshape(-1, 3), part["effect_m"].to_numpy().reshape(-1, 3))
    return out


def residuals_frame(residuals: dict[str, dict[str, np.ndarray]], rows: dict[str, np.ndarray] | None = None
                    ) -> pd.DataFrame:
    """Long table of the residuals before and after: when, set, point, x_m, y_m, z_m, and with
    rows ({set: (n,)}) the sensor table's row of each point (so a pose can be found for it)."""
    frames = [pd.DataFrame({"when": when, "set": set_name, "point": np.arange(len(r), dtype=np.int64),
                            "x_m": r[:, 0], "y_m": r[:, 1], "z_m": r[:, 2],
                            **({"row": np.asarray(rows[set_name], dtype=np.int64)} if rows else {})})
              for when, per_set in residuals.items() for set_name, r in per_set.items()]
    return pd.concat(frames, ignore_index=True)


def residuals_of(frame: pd.DataFrame) -> dict[str, dict[str, np.ndarray]]:
    """`residuals_frame` back to {when: {set: (n, 3) m}}."""
    return {when: {s: part.sort_values("point")[["x_m", "y_m", "z_m"]].to_numpy()
                   for s, part in per_when.groupby("set", sort=False)}
            for when, per_when in frame.groupby("when", sort=False)}


def campaign_table(tables: dict[str, pd.DataFrame], reports: dict[str, dict]) -> pd.DataFrame:
    """Before and after of every sensor of a campaign, with the effects each added, for the report."""
    frames = []
    for sensor, table in tables.items():
        added = ", ".join(reports[sensor]["effects_added"]) or "none"
        frames.append(table.assign(Sensor=sensor, **{"Effects added": added}))
    out = pd.concat(frames, ignore_index=True)
    first = ["Sensor", "Effects added"]
    return out[first + [c for c in out.columns if c not in first]]


def closure_table(reports: dict[str, dict]) -> pd.DataFrame:
    """The closure test of every sensor: after each step, the cross-validated RMS per axis, the
    noise floor, their ratio, the share of the structured residual the step removed, the verdict;
    the last row of a sensor says where what is left lives (the residual GP's joints)."""
    rows = []
    for sensor, report in reports.items():
        test, gp = report["closure"], report.get("residual_gp")
        shares = test["share_of_structured_residual"]
        where = ("GP not tried" if gp is None else ", ".join(gp["depends_on"]) if gp["structure_found"]
                 else "no structure the GP can predict")
        for k, step in enumerate(test["rounds"]):
            last = k == len(test["rounds"]) - 1
            rows.append({"Sensor": sensor, "After": step["after"], "CV RMS per axis (mm)": step["rms_per_axis_mm"],
                         "Noise floor (mm)": test["noise_floor_mm"], "Ratio": step.get("ratio_to_floor"),
                         "Share removed (%)": (100.0 * shares[step["after"]]
                                               if shares.get(step["after"]) is not None else None),
                         "Verdict": step["text"], "Residual depends on": where if last else ""})
    return pd.DataFrame(rows)


def candidates_table(reports: dict[str, dict]) -> pd.DataFrame:
    """Every candidate's scores in every round, per sensor: evidence gain, cross-validated fall
    (pose-grouped, in standard errors), BIC gain, the fraction of the residual it explains, and
    whether it was added. A candidate `select` skipped (nothing of it identifiable) has no scores:
    NaN, and the reason in the last column. A laser tracker's range/transverse noise model
    (`remaster.noise`) gets a row of its own, after the rounds: its evidence gain, or why it was
    not offered."""
    rows = []
    nan = float("nan")
    for sensor, report in reports.items():
        for name, rounds in report["candidates"].items():
            for entry in rounds:
                added = (entry["round"] <= len(report["effects_added"])
                         and report["effects_added"][entry["round"] - 1] == name)
                skipped = "skipped" in entry
                rows.append({"Sensor": sensor, "Round": entry["round"], "Candidate": name,
                             "Log evidence gain": entry.get("log_evidence_gain", nan),
                             "CV RMSE (mm)": entry.get("cv_rmse_mm", nan),
                             "CV fall (%)": 100.0 * entry.get("cv_gain", nan),
                             "CV fall / SE": entry.get("cv_mse_fall_in_se", nan),
                             "BIC gain": entry.get("bic_gain", nan),
                             "Explained (%)": 100.0 * entry.get("explained_fraction", nan),
                             "Added": f"skipped: {entry['skipped']}" if skipped else "yes" if added else ""})
        noise_model = report.get("noise_model") or {}
        if noise_model.get("offered"):
            rows.append({"Sensor": sensor, "Round": nan, "Candidate": "noise: range/transverse",
                         "Log evidence gain": noise_model["log_evidence_gain"], "CV RMSE (mm)": nan, "CV fall (%)": nan,
                         "CV fall / SE": nan, "BIC gain": nan, "Explained (%)": nan,
                         "Added": "yes" if noise_model["chosen"] == "range_transverse" else ""})
        elif noise_model.get("why") and noise_model["why"] != "not a laser tracker":
            rows.append({"Sensor": sensor, "Round": nan, "Candidate": "noise: range/transverse",
                         **{k: nan for k in ("Log evidence gain", "CV RMSE (mm)", "CV fall (%)", "CV fall / SE",
                                             "BIC gain", "Explained (%)")},
                         "Added": f"not offered: {noise_model['why']}"})
    return pd.DataFrame(rows)


def settings_from(config: Mapping, priors_config: Mapping | None = None,
                  convergence: Mapping | None = None) -> LoopSettings:
    """LoopSettings from the workflow's `loop_closure` configuration, its `priors` section and the
    convergence criteria of the fit's cross-check (`fit/cross_check`: max_rhat, min_ess)."""
    payload = config.get("payload", {})
    priors_config = with_defaults(priors_config)
    criteria = dict(CONVERGENCE_DEFAULT)
    criteria.update({k: v for k, v in (convergence or {}).items() if k in ("max_rhat", "min_ess")})
    if "max_doublings" in config:
        criteria["max_doublings"] = int(config["max_doublings"])
    return LoopSettings(min_log_evidence_gain=float(config["min_log_evidence_gain"]),
                        cv_folds=int(config["cv_folds"]), cv_standard_errors=float(config["cv_standard_errors"]),
                        model=ModelSettings(payload_mass=float(payload.get("mass", 1.0)),
                                            payload_com=tuple(payload.get("com", (0.0, 0.0, 0.02)))),
                        priors=priors_from(priors_config), priors_config=dict(priors_config),
                        mcmc=dict(config["mcmc"]) if config.get("mcmc") else None, convergence=criteria,
                        residual_gp=_gp_settings(config.get("residual_gp")),
                        closure_ratio=float(config.get("closure_ratio", closure.CLOSURE_RATIO)),
                        tracker_noise=_tracker_noise_settings(config.get("tracker_noise")))


def _gp_settings(section: Mapping | None) -> dict | None:
    """The residual GP's settings from its config section ({'enabled', 'subset', 'inducing'})."""
    section = {**GP_DEFAULT, "enabled": True, **(section or {})}
    return {k: int(section[k]) for k in GP_DEFAULT} if section["enabled"] else None


def _tracker_noise_settings(section: Mapping | None) -> dict | None:
    """The tracker noise model's prior from its config section ({'enabled', 'growth_per_m', 'growth_factor'})."""
    section = {**TRACKER_NOISE_DEFAULT, "enabled": True, **(section or {})}
    return {k: float(section[k]) for k in TRACKER_NOISE_DEFAULT} if section["enabled"] else None
