"""Loop closure (issue 5/7): what the zero-offset model leaves in the residuals, named and removed.

Per campaign and sensor, after the zero-offset fit:

1. Diagnose: for each candidate block (`blocks.EXTENSIONS`; drift only when the table has a
   time or temperature column), fit current + candidate by least squares and score it by
   - its BIC gain, BIC = k ln(SS / k) + p ln k (k residual components, SS their sum of squares,
     p free parameters including sigma), gain = BIC(current) - BIC(candidate): the same
     evidence measure for every candidate (a Laplace log-evidence would need priors on the
     extension parameters, which a flat prior does not give);
   - its relative fall of the post-registration RMSE on the held-out VALIDATION set, predicted
     with the optimization fit's parameters and registration;
   - its signature: the optimization residual of the current fit against the change in the
     prediction the candidate's fit makes (points on the diagonal: the effect is what is left).
2. Decide: greedy forward selection. Among the candidates whose BIC gain exceeds
   `min_bic_gain` AND whose validation RMSE falls by more than `min_validation_gain`
   (relative), add the one of largest BIC gain, refit, and repeat with the others.
3. Refit the final model by least squares (the last round's fit) and, when settings are
   given, by adaptive Metropolis (`fit.sample`, method 'default'), so that the added
   parameters carry uncertainty; report before/after accuracy and how far the zero-offsets
   moved.

Accuracy measures (per set, in mm): post-registration RMSE sqrt(mean |E_i|^2) over the points,
the RMS per axis (comparable to sigma and the sensor noise), the paper's mean post-registration
error mean |E_i|, and the paper's relative error |d(ref) - d(model)| over the pairs of
configurations of each pose (`remaster.metrics`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import blocks, fit, metrics, samplers
from .blocks import BlockModel, ModelSettings, Readings, Reduction
from .campaign import Campaign, SensorData
from .kinematics import KinematicChain
from .model import DEG, MM, SIGMA

SETS = ("optimization", "validation")
MCMC_DEFAULT = {"chains": 2, "samples": 20000, "burn_in": 8000}
# What the data determine is settled, unit-free, by `blocks.identifiable_extension`; least
# squares' own test (singular values of J in display units below rcond x the largest) would judge
# by the units instead (a compliance step of 1 urad/(N m) against a degree), so it is left to
# catch round-off only.
ROUND_OFF = 1e-12


@dataclass(frozen=True)
class LoopSettings:
    """candidates: extension blocks to try; min_bic_gain: the evidence an effect needs;
    min_validation_gain: the relative fall of the validation RMSE it needs; model: payload and
    drift column; mcmc: {'chains', 'samples', 'burn_in'} of the final adaptive-Metropolis refit,
    None for least squares/Laplace only."""

    candidates: tuple[str, ...] = blocks.EXTENSIONS
    min_bic_gain: float = 10.0
    min_validation_gain: float = 0.02
    model: ModelSettings = ModelSettings()
    mcmc: dict | None = field(default_factory=lambda: dict(MCMC_DEFAULT))

    def report(self) -> dict:
        return {"candidates": list(self.candidates), "min_bic_gain": self.min_bic_gain,
                "min_validation_gain": self.min_validation_gain,
                "payload_mass_kg": self.model.payload_mass, "payload_com_m": list(self.model.payload_com),
                "drift_column": self.model.drift_column, "mcmc": self.mcmc}


# --------------------------------------------------------------------------- accuracy measures


def accuracy(measured, predicted, poses) -> dict:
    """Post-registration and relative accuracy (mm) of predictions (n, 3) against measurements
    (n, 3), both in the sensor frame; poses (n,) group the relative measure's pairs
    (`remaster.metrics`)."""
    error = np.asarray(measured) - np.asarray(predicted)
    norms = metrics.post_registration_errors(measured, predicted)
    relative = metrics.interval_summary(metrics.relative_errors(measured, predicted, poses))
    return {"points": int(len(norms)), "rmse_mm": float(np.sqrt(np.mean(norms**2)) / MM),
            "rms_per_axis_mm": float(np.sqrt(np.mean(error**2)) / MM), "mean_error_mm": float(norms.mean() / MM),
            "error_q97.5_mm": float(np.quantile(norms, 0.975) / MM), "relative_pairs": relative["count"],
            "relative_mean_mm": relative["mean"] / MM if relative["count"] else None}


def bic(result: samplers.LaplaceResult) -> float:
    """k ln(SS / k) + p ln k: the Gaussian likelihood maximised over sigma, p = parameters + sigma."""
    k = result.n_residuals
    return k * math.log(2.0 * result.cost / k) + (len(result.theta_map) + 1) * math.log(k)


# --------------------------------------------------------------------------- one least-squares fit


@dataclass(frozen=True, eq=False)
class Fitted:
    """One model fitted by least squares on the optimization set, with its validation twin
    (same parameters and registration) and the identifiability reduction of its extensions."""

    model: BlockModel
    validation: BlockModel
    result: samplers.LaplaceResult
    reduction: Reduction

    @property
    def theta(self) -> np.ndarray:
        return self.result.theta_map

    @property
    def bic(self) -> float:
        return bic(self.result)

    def values(self) -> dict[str, float]:
        return self.model.values(self.theta)

    def residuals(self, set_name: str) -> np.ndarray:
        """(n, 3) measured - predicted on a set, m."""
        return (self.model if set_name == "optimization" else self.validation).residuals(self.theta)

    def accuracy(self, poses: Mapping[str, np.ndarray]) -> dict:
        """{set: `accuracy`} with the optimization fit's parameters, poses {set: (n,) labels}."""
        out = {}
        for set_name, model in zip(SETS, (self.model, self.validation)):
            out[set_name] = accuracy(model.measured, model.predict(self.theta), poses[set_name])
        return out


def fit_blocks(chain: KinematicChain, data: Mapping[str, Readings], marker, t_nr, extensions: Sequence[str],
               base_held: Mapping[str, float], start: Mapping[str, float] | None = None) -> Fitted:
    """Least-squares fit (with Laplace covariance) of base + extensions on data['optimization'],
    from `start` ({name: value}; 0 for the others)."""
    model, reduction = blocks.extended_model(chain, data["optimization"], marker, t_nr, extensions, base_held)
    result = samplers.least_squares_laplace(lambda theta: model.residuals(theta).ravel(), model.vector(start or {}),
                                            model.scale, names=model.names, rcond=ROUND_OFF)
    return Fitted(model, model.on(data["validation"]), result, reduction)


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


def score(current: Fitted, candidate: Fitted, validation_rmse_mm: float, poses) -> dict:
    """A candidate's scores against the current fit, whose validation RMSE is given (JSON-ready)."""
    after = candidate.accuracy(poses)["validation"]["rmse_mm"]
    return {"bic_gain": current.bic - candidate.bic, "validation_rmse_mm": after,
            "validation_gain": 1.0 - after / validation_rmse_mm, "sigma_mm": candidate.result.sigma_map / MM,
            "parameters": list(candidate.reduction.kept), "dropped": dict(candidate.reduction.dropped),
            "condition_number": candidate.reduction.condition_number}


@dataclass(frozen=True, eq=False)
class Selection:
    """The greedy forward selection: final fit, the base fit, the rounds (JSON-ready) and the
    signatures {round: {candidate: Signature}}."""

    base: Fitted
    final: Fitted
    added: tuple[str, ...]
    rounds: list[dict]
    signatures: dict[int, dict[str, Signature]]


def select(chain: KinematicChain, data: Mapping[str, Readings], marker, t_nr, base_held: Mapping[str, float],
           poses, settings: LoopSettings) -> Selection:
    """Diagnose and decide (module docstring, steps 1 and 2)."""
    base = current = fit_blocks(chain, data, marker, t_nr, (), base_held)
    remaining = [c for c in settings.candidates if blocks.available(c, data["optimization"])]
    added: list[str] = []
    rounds, signatures = [], {}
    while remaining:
        number = len(rounds) + 1
        reference = current.accuracy(poses)["validation"]["rmse_mm"]
        residual, prediction = current.residuals("optimization"), current.model.predict(current.theta)
        scores, fits, signatures[number] = {}, {}, {}
        for candidate in remaining:
            try:
                fitted = fit_blocks(chain, data, marker, t_nr, tuple(added) + (candidate,), base_held, current.values())
            except samplers.NotIdentifiable as exc:
                scores[candidate] = {"skipped": f"not identifiable: {exc}"}
                continue
            if not fitted.reduction.kept:
                scores[candidate] = {"skipped": "no parameter of this block is identifiable from these data",
                                     "dropped": dict(fitted.reduction.dropped)}
                continue
            fits[candidate] = fitted
            signature = signatures[number][candidate] = Signature(residual,
                                                                  fitted.model.predict(fitted.theta) - prediction)
            scores[candidate] = {**score(current, fitted, reference, poses),
                                 "explained_fraction": signature.explained}
            scores[candidate]["passed"] = bool(scores[candidate]["bic_gain"] > settings.min_bic_gain
                                               and scores[candidate]["validation_gain"] > settings.min_validation_gain)
        passing = [c for c in fits if scores[c]["passed"]]
        best = max(passing, key=lambda c: scores[c]["bic_gain"]) if passing else None
        rounds.append({"round": number, "model": list(blocks.BASE) + added, "scores": scores, "added": best})
        if best is None:
            break
        current = fits[best]
        added.append(best)
        remaining.remove(best)
    return Selection(base, current, tuple(added), rounds, signatures)


# --------------------------------------------------------------------------- refit and report


def parameter_table(fitted: Fitted, samples: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per parameter (held ones included) and sigma: mean, std and 95 % interval in SI and in
    display units, status. From the MCMC samples when given, else the Laplace approximation
    (mean = MAP, interval +-1.96 std)."""
    model = fitted.model
    names = list(model.names) + [SIGMA]
    if samples is not None:
        values = samples[names]
        mean, std = values.mean().to_numpy(), values.std(ddof=1).to_numpy()
        low, high = values.quantile(0.025).to_numpy(), values.quantile(0.975).to_numpy()
        source = "adaptive Metropolis"
    else:
        mean, std = fitted.result.moments()[:2]
        low, high = mean - 1.959964 * std, mean + 1.959964 * std
        source = "least squares + Laplace"
    free = {n: (m, s, lo, hi) for n, m, s, lo, hi in zip(names, mean, std, low, high)}
    reasons = {**{n: "held: not identifiable" for n in model.fixed}, **fitted.reduction.dropped}
    rows = []
    for name, scale, unit in list(zip(model.all_names, model.all_scale, model.all_unit)) + [(SIGMA, MM, "mm")]:
        m, s, lo, hi = free.get(name, (model.fixed.get(name, 0.0), np.nan, np.nan, np.nan))
        rows.append({"parameter": name, "block": model.block_of.get(name, "noise"), "mean": m, "std": s,
                     "q2.5": lo, "q97.5": hi, "unit": unit, "mean_display": m / scale, "std_display": s / scale,
                     "q2.5_display": lo / scale, "q97.5_display": hi / scale,
                     "status": "estimated" if name in free else reasons.get(name, "held"), "source": source})
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
    residuals: {'before'|'after': {set: (n, 3) m}}; samples: the MCMC refit (SI) or None."""

    report: dict
    table: pd.DataFrame
    signatures: dict[int, dict[str, Signature]]
    residuals: dict[str, dict[str, np.ndarray]]
    samples: pd.DataFrame | None


def _laplace_start(result: samplers.LaplaceResult) -> dict:
    """What `fit.sample` reads of a Laplace report."""
    return {"theta_map": result.theta_map.tolist(), "sigma_map": result.sigma_map,
            "covariance": result.covariance.tolist(), "sigma_std": result.sigma_std}


def close_loop(chain: KinematicChain, sensor: SensorData, t_nr, base_held: Mapping[str, float],
               rng: np.random.Generator, settings: LoopSettings = LoopSettings(), exclude=()) -> LoopClosure:
    """Diagnose, decide and refit for one sensor. t_nr (4, 4): the fit's initial registration;
    base_held: the zero-offset fit's held parameters (identifiability analysis); exclude: table
    rows the fit left out as gross errors (left out here too); rng feeds the MCMC refit only."""
    data = {s: blocks.readings(chain, sensor, s, settings.model, exclude) for s in SETS}
    poses = {s: sensor.table.loc[data[s].rows, "pose"].to_numpy() for s in SETS}
    selection = select(chain, data, sensor.marker, t_nr, base_held, poses, settings)
    base, final = selection.base, selection.final

    samples, mcmc = None, None
    if settings.mcmc is not None:
        started = time.perf_counter()
        chains = fit.sample(final.model, _laplace_start(final.result), "default", settings.mcmc, rng)
        samples = fit.samples_frame(chains)
        mcmc = fit.sampler_diagnostics(chains, time.perf_counter() - started)
    before_table = parameter_table(base)
    after_table = parameter_table(final, samples)
    sigma_before = base.result.sigma_mean
    sigma_after = float(after_table.set_index("parameter").loc[SIGMA, "mean"])
    before, after = base.accuracy(poses), final.accuracy(poses)
    counts = (len(base.model.names) + 1, len(final.model.names) + 1)
    report = {
        "sensor": sensor.name, "evidence": "BIC gain: BIC = k ln(SS/k) + p ln k (k residual components, p free "
        "parameters + sigma), gain = BIC(current model) - BIC(with the candidate)",
        "settings": settings.report(),
        "effects_added": list(selection.added),
        "candidates": _per_candidate(selection.rounds),
        "rounds": [{"round": r["round"], "model": r["model"], "added": r["added"]} for r in selection.rounds],
        "validation_rmse_before_mm": before["validation"]["rmse_mm"],
        "validation_rmse_after_mm": after["validation"]["rmse_mm"],
        "sigma_before_mm": sigma_before / MM, "sigma_after_mm": sigma_after / MM,
        "before": before, "after": after,
        "identifiability": final.reduction.report(),
        "refit": {"least_squares": {"names": list(final.model.names), "theta_map": final.theta.tolist(),
                                    "std": final.result.std.tolist(), "sigma_map_mm": final.result.sigma_map / MM,
                                    "sigma_mean_mm": final.result.sigma_mean / MM, "bic": final.bic},
                  "mcmc": mcmc,
                  "parameters": after_table.replace({np.nan: None}).to_dict(orient="records")},
        "zero_offset_shifts": zero_offset_shifts(before_table, after_table),
    }
    table = before_after_table(before, after, sigma_before, sigma_after, counts)
    residuals = {"before": {s: base.residuals(s) for s in SETS}, "after": {s: final.residuals(s) for s in SETS}}
    return LoopClosure(report, table, selection.signatures, residuals, samples)


def _per_candidate(rounds: list[dict]) -> dict[str, list[dict]]:
    """{candidate: [its scores in each round it was tried, with the round number]}."""
    out: dict[str, list[dict]] = {}
    for r in rounds:
        for name, scores in r["scores"].items():
            out.setdefault(name, []).append({"round": r["round"], **scores})
    return out


def loop_closure_stage(campaign: Campaign, sensor: str, registration_report: dict, laplace: dict,
                       rng: np.random.Generator, settings: LoopSettings = LoopSettings()) -> LoopClosure:
    """Loop closure of one sensor of a campaign after its zero-offset fit (the registration and
    Laplace reports of `fit`)."""
    result = close_loop(campaign.chain, campaign.sensors[sensor], np.array(registration_report["T_NR"]),
                        laplace["identifiability"]["held_at_controller_value"], rng, settings,
                        laplace.get("excluded_rows_outliers", ()))
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


def residuals_frame(residuals: dict[str, dict[str, np.ndarray]]) -> pd.DataFrame:
    """Long table of the residuals before and after: when, set, point, x_m, y_m, z_m."""
    frames = [pd.DataFrame({"when": when, "set": set_name, "point": np.arange(len(r), dtype=np.int64),
                            "x_m": r[:, 0], "y_m": r[:, 1], "z_m": r[:, 2]})
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


def candidates_table(reports: dict[str, dict]) -> pd.DataFrame:
    """Every candidate's scores in every round, per sensor: BIC gain, validation RMSE and its fall,
    the fraction of the residual it explains, and whether it was added. A candidate `select`
    skipped (nothing of it identifiable) has no scores: NaN, and the reason in the last column."""
    rows = []
    nan = float("nan")
    for sensor, report in reports.items():
        for name, rounds in report["candidates"].items():
            for entry in rounds:
                added = (entry["round"] <= len(report["effects_added"])
                         and report["effects_added"][entry["round"] - 1] == name)
                skipped = "skipped" in entry
                rows.append({"Sensor": sensor, "Round": entry["round"], "Candidate": name,
                             "BIC gain": nan if skipped else entry["bic_gain"],
                             "Validation RMSE (mm)": nan if skipped else entry["validation_rmse_mm"],
                             "Validation fall (%)": nan if skipped else 100.0 * entry["validation_gain"],
                             "Explained (%)": 100.0 * entry.get("explained_fraction", nan),
                             "Added": f"skipped: {entry['skipped']}" if skipped else "yes" if added else ""})
    return pd.DataFrame(rows)


def settings_from(config: Mapping) -> LoopSettings:
    """LoopSettings from the workflow's `loop_closure` configuration."""
    payload = config.get("payload", {})
    return LoopSettings(min_bic_gain=float(config["min_bic_gain"]),
                        min_validation_gain=float(config["min_validation_gain"]),
                        model=ModelSettings(payload_mass=float(payload.get("mass", 1.0)),
                                            payload_com=tuple(payload.get("com", (0.0, 0.0, 0.02)))),
                        mcmc=dict(config["mcmc"]) if config.get("mcmc") else None)
