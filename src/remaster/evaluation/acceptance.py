"""The validation set as the acceptance test: does what the validation set measured lie within what
the calibration claims at its configurations, noise included? Read after every choice was made
(the loop closure's effects, its refit, the paper's fit); nothing here selects or tunes anything
but the verdict.

**The check** (a posterior predictive check, one per model: the loop-closed model and the paper's):

- statistic T: the RMS per axis of the validation residuals, sqrt(mean over rows and axes of
  e_i^2), e_i = y_i - p_ref(q_i), y the measured positions (sensor frame), p_ref the model's
  prediction at its posterior mean with the optimization set's registration as fitted (a residual
  GP, when the loop added one, at its mean);
- its replicates, one per posterior draw d (whole rows of the posterior: the registration and every
  parameter; the loop's residual GP drawn jointly across the configurations):
  T_d = RMS of (p_d(q) + n_d - p_ref(q)), n_d the noise the calibration claims: the instrument's
  own (the per-point std columns where the table has them, else the sensor's stated `noise`) and
  the model error the calibration declares, both independent per axis. The declared model error
  is zero where the loop closure says "closed" (the claim is then the noise), else what it
  measured on the optimization set beyond the noise floor (the structured residual per axis of
  its pose-grouped cross-validation: the final model's for the loop-closed model, the zero-offset
  model's for the paper's); a campaign that is "not closed"
  thus passes only as far as it declared its residual, and the certificate states it. Without a
  stated noise, point std or repeats the test falls back to each draw's fitted sigma (the
  tracker's range / transverse shape when the loop chose it), which absorbs what the model lacks:
  it then tests only that the validation set is like the optimization set, and says so;
- p = share of replicates with T_d >= T; the model FAILS when p < `level` (config
  `acceptance/level`). Under a correct model p is uniform and a model fails at the rate `level`.
  Where a model error was declared, the same test against the instrument's noise alone is
  reported beside it (`at_noise`: what a closed loop would claim, `Claim.closed`: the noise alone,
  and the posterior's spread scaled down by the instrument's noise over the fitted sigma, as a fit
  whose residual were the noise would have it; the fitted sigma's posterior alone is wide enough
  to pass a model missing an effect): a model missing an effect fails that one whatever it
  declared, and the certificate says the calibration holds as far as it declared, not to the
  sensor's noise.
  A model whose validation RMS per axis exceeds `plausible_residual_mm` fails whatever its p: no
  calibrated arm is off by that much, a unit slip or a wrong robot description is.

**A validation set that cannot test** gets no pass. Rows whose joint readings agree to within
SAME_CONFIGURATION (0.1 deg) in every joint are one configuration (`distinct_configurations`):
between readings dq apart the calibration's error e(q) changes by about L |dq| |delta| (lever arm
L, residual angular error delta), 0.8 um at L = 1 m, |dq| = 0.1 deg sqrt(7) and delta = 0.01 deg,
below any sensor's noise, so such rows measure one point of the error again; different IK solutions
of one target (the marker at one point, the joints far apart) stay distinct. With fewer distinct
configurations than `configurations_needed` (three numbers each for the paper model's free
parameters, registration and zero-offsets: 4 for a 6-axis arm, 5 for a 7-axis one; never fewer
than 3, which a rigid refit needs) some combination of the parameters is invisible whatever the
number of rows, and one configuration's error is a translation the registration absorbs: the
verdict is "cannot test", with the count; the checks are still made and reported (a failure at
those configurations is said, undiagnosed: a move and a calibration error look alike there), and
the ISO 9283 repeatability RP of the repeated configurations is given (`repeats_report`).

**The recommended model is the loop-closed one**, chosen on the optimization set before the
validation set is read; the validation set chooses nothing. Its check is the verdict; the paper
model's check is shown beside it.

**Diagnosis of a failure of the loop-closed model**, in this order:

(0) the validation RMS beyond `plausible_residual_mm`: the model does not describe the arm;
(a) the registration refitted on the validation rows, the model's parameters fixed: the rigid
    transform M (closed form, Kabsch) that best maps the model's predictions onto the validation
    readings, the refit registration being M T_opt. The same refit applied to every replicate
    (it absorbs six degrees of freedom there too) gives the refit check. When the refit removes at
    least `registration_share` of the excess mean square (T^2 - median T_d^2), the diagnosis is "the sensor or the robot's base moved between the sets", with the
    move M: its translation (mm, sensor frame), its rotation angle (deg), and the displacement at
    the validation points' centre; when the refit check still fails, a robot error remains
    beyond the move, and the diagnosis says so;
(b) else "the calibration is not confirmed".

Validation rows another stage flagged as gross errors (`LoopReport.gross_errors['validation']`,
when the report carries it) are left out and listed. SI inside; the report is in mm and degrees
where the names say so.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields

import numpy as np
import pandas as pd

from .. import noise, spatial
from ..errors import InputError, format_rows, report_reader, require_columns
from ..files import read_json, write_json
from ..inference import blocks
from ..inference.blocks import BlockModel
from ..inference.bounds import QUANTILE
from ..inference.gp import loop_candidate
from ..inference.laplace_report import LaplaceReport
from ..inference.metrics import rms_per_axis
from ..inference.model import SIGMA
from ..inference.readings import ModelSettings, Readings, readings
from ..loop.result import LoopReport, LoopResults
from ..robot import registration
from ..robot.kinematics import KinematicChain
from ..units import DEG, MM

MODELS = ("loop", "paper")
GP = "residual_gp"
PASS, FAIL, UNTESTED, CANNOT_TEST = "pass", "fail", "not tested", "cannot test"
VERDICTS = (PASS, FAIL, UNTESTED, CANNOT_TEST)
MIN_VALIDATION_ROWS = 3  # fewer measured validation rows: no test made, the certificate says so
# rows whose joint readings all agree to this are one configuration of the test (module docstring)
SAME_CONFIGURATION = 0.1 * DEG
MIN_CONFIGURATIONS = 3  # a rigid refit (the diagnosis of a move) needs three points off one line
IMPLAUSIBLE, MOVED, NOT_CONFIRMED = "does_not_describe_the_arm", "sensor_moved", "not_confirmed"
DIAGNOSES = {
    IMPLAUSIBLE: "the model does not describe the arm (check the units of the marker, the positions and the robot "
    "description)",
    MOVED: "the sensor or the robot's base moved between the sets",
    NOT_CONFIRMED: "the calibration is not confirmed",
}
STATISTIC = (
    "RMS per axis of the validation residuals (measured - the model's prediction at its posterior mean, "
    "optimization registration as fitted), against its replicates from posterior draws with the noise the "
    "calibration claims: the instrument's and the model error it declares"
)
INSTRUMENT, FITTED = "the instrument's stated noise", "the fitted sigma (no stated noise, point std or repeats)"
# the sources of a claim's replicates (`Claim.parts`), as the uncertainty budget names them
CALIBRATION = "calibration: the posterior of the registration and every parameter"
GP_SOURCE = "residual GP: what no parametric effect explains, drawn jointly"
DECLARED = "model error the calibration declares (the loop not closed)"
NOISE = "instrument noise (stated noise or point std)"
FITTED_NOISE = "the fitted sigma: noise and whatever the model lacks together (no noise stated)"


# --------------------------------------------------------------------------- the check itself


def refit_residuals(reference, targets) -> tuple[np.ndarray, np.ndarray]:
    """(residuals (m, n, 3) of targets (m, n, 3) after the rigid transform that best maps reference
    (n, 3) onto each, those transforms (m, 4, 4): `robot.registration.rigid_transforms`)."""
    moves = registration.rigid_transforms(reference, targets)
    # a batched matmul, not einsum: 3x faster on (m, n, 3) (the acceptance test's largest cost)
    mapped = np.asarray(reference) @ np.swapaxes(moves[:, :3, :3], -1, -2) + moves[:, None, :3, 3]
    return np.asarray(targets) - mapped, moves


def p_value(observed: float, replicates) -> float:
    """Share of replicates at or above the observed statistic (one-sided: a larger error fails)."""
    return float(np.mean(np.asarray(replicates, dtype=float) >= observed))


def move_report(move, points) -> dict:
    """A rigid move M (4, 4) of the sensor's readings (m' = R m + t, sensor frame) in mm and deg:
    its translation, its rotation (angle and rotation vector), and the displacement it gives the
    centre of points (n, 3) m."""
    move = np.asarray(move, dtype=float)
    centre = np.asarray(points, dtype=float).mean(axis=0)
    at_centre = spatial.transform_points(move, centre[None])[0] - centre
    return {
        "translation_mm": (move[:3, 3] / MM).tolist(),
        "translation_norm_mm": float(np.linalg.norm(move[:3, 3]) / MM),
        "rotation_deg": float(spatial.rotation_angle(move[:3, :3]) / DEG),
        "rotation_vector_deg": (spatial.matrix_to_rotation_vector(move[:3, :3]) / DEG).tolist(),
        "displacement_at_centre_mm": (at_centre / MM).tolist(),
        "displacement_at_centre_norm_mm": float(np.linalg.norm(at_centre) / MM),
        "transform": move.tolist(),
        "convention": "validation readings = M (the model's prediction with the optimization registration), "
        "sensor frame; the refit registration is M T_opt",
    }


@dataclass(frozen=True, eq=False)
class Claim:
    """What a model claims at the validation readings: reference (n, 3) m its prediction at the
    posterior mean (sensor frame, a residual GP's mean added); model: the parametric model on those
    readings; theta (m, P) its posterior draws' free parameters, sigma (m,) m their noise std;
    gp_draws: count -> rng -> (count, n, 3) m draws of the residual GP at the readings, jointly across
    them, sensor frame (None without one), gp_mean (n, 3) m its mean (sensor frame) or 0; effects: the model's blocks; source: where the draws come from;
    instrument (n, 3) m: the instrument's noise std per reading and axis, declared m: the model error
    per axis the calibration declares; without `instrument` the draws' own sigma is the noise;
    calibration_scale: the factor on the posterior's deviations (1 but in `closed`)."""

    reference: np.ndarray
    model: BlockModel
    theta: np.ndarray
    sigma: np.ndarray
    effects: tuple[str, ...]
    source: str
    gp_draws: Callable[[int, np.random.Generator], np.ndarray] | None = None
    gp_mean: np.ndarray | float = 0.0
    instrument: np.ndarray | None = None
    declared: float = 0.0
    calibration_scale: float = 1.0

    def closed(self) -> Claim:
        """What a closed loop would claim with this model: the instrument's noise alone, no declared
        model error, and the posterior's spread as a fit whose residual is that noise would have it.
        The posterior was made with the fitted sigma, which carries what the model lacks; its spread
        grows with that sigma, so it is scaled by the instrument's RMS over the draws' median sigma
        (never widened). Directions the priors decide shrink too, so the claim is, if anything,
        narrower than such a fit's."""
        if self.instrument is None:
            return self
        fitted = float(np.median(self.sigma))
        instrument = float(np.sqrt(np.mean(np.asarray(self.instrument, dtype=float) ** 2)))
        scale = min(1.0, instrument / fitted) if fitted > 0 else 1.0
        return dataclasses.replace(self, declared=0.0, calibration_scale=scale)

    def replicates(self, rows, rng: np.random.Generator) -> np.ndarray:
        """Replicated validation readings (k, n, 3) m of the draws `rows` (k,): each draw's
        prediction, its GP draw when there is a GP, and the claimed noise."""
        return self.reference + sum(self.parts(rows, rng).values())

    def parts(self, rows, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """The replicates' deviations from the reference, (k, n, 3) m each, by source (`SOURCES`):
        the posterior of the parameters, the residual GP (when there is one), the declared model
        error (when there is one) and the noise; independent, so their variances add."""
        points = self.model.predict(self.theta[rows])
        gp = self.gp_mean if self.gp_draws is None else self.gp_draws(len(points), rng)
        out = {CALIBRATION: self.calibration_scale * (points + self.gp_mean - self.reference)}
        if self.gp_draws is not None:
            out[GP_SOURCE] = gp - self.gp_mean
        if self.instrument is not None:
            if self.declared > 0:
                out[DECLARED] = self.declared * rng.standard_normal(points.shape)
            out[NOISE] = self.instrument[None] * rng.standard_normal(points.shape)
            return out
        draws = _noise_draws(self.sigma[rows], self.model.measured, points.shape, rng, self.model.noise)
        # a loop model on a table with per-point stds: each row's noise is sigma times its weight
        weights = getattr(getattr(self.model, "data", None), "weights", None)
        out[FITTED_NOISE] = draws if weights is None else draws * weights
        return out


CHUNK_VALUES = 2**21  # draws x rows x 3 values replicated at once: 16 MB per array whatever the campaign's size


def check(
    measured, claim: Claim, level: float, registration_share: float, rng: np.random.Generator, plausible: float
) -> dict:
    """The check of one model on validation readings measured (n, 3) m (JSON-ready, mm): observed
    and replicated statistic, p-value and pass, and the same with the registration refitted on the
    validation rows (`refit`: its move, and the share of the excess mean square it removes); the
    noise the claim used; `plausible` (m): a validation RMS per axis above it fails whatever the
    p-value. The replicates are made a chunk of draws at a time (rng: their GP draws and noise)."""
    measured = np.asarray(measured, dtype=float)
    observed = float(rms_per_axis(measured - claim.reference))
    refit_obs, moves = refit_residuals(claim.reference, measured[None])
    observed_refit = float(rms_per_axis(refit_obs[0]))
    replicates, replicates_refit = _replicated(claim, rng)
    excess = observed**2 - float(np.median(replicates**2))
    excess_refit = observed_refit**2 - float(np.median(replicates_refit**2))
    # the share of the excess the refit removes, in [0, 1]; None when there is no excess to remove
    removed = min(1.0, max(0.0, 1.0 - max(excess_refit, 0.0) / excess)) if excess > 0 else None
    p, p_refit = p_value(observed, replicates), p_value(observed_refit, replicates_refit)
    described = observed <= plausible
    at_noise = None
    if claim.instrument is not None:
        # the same test against what "closed" would claim (`Claim.closed`); a model missing an
        # effect fails it, whatever error it declared
        alone = replicates if claim.declared == 0 else _replicated(claim.closed(), rng, refit=False)[0]
        p_alone = p_value(observed, alone)
        at_noise = {
            "replicate_median_mm": float(np.median(alone) / MM),
            "replicate_p95_mm": float(np.quantile(alone, QUANTILE) / MM),
            "p_value": p_alone,
            "passed": bool(p_alone >= level and described),
        }
    return {
        "effects": list(claim.effects),
        "draws_from": claim.source,
        "draws": int(len(replicates)),
        "noise": INSTRUMENT if claim.instrument is not None else FITTED,
        "instrument_rms_per_axis_mm": None
        if claim.instrument is None
        else float(np.sqrt(np.mean(claim.instrument**2)) / MM),
        "declared_model_error_mm": claim.declared / MM if claim.instrument is not None else None,
        "observed_rms_per_axis_mm": observed / MM,
        "replicate_median_mm": float(np.median(replicates) / MM),
        "replicate_p95_mm": float(np.quantile(replicates, QUANTILE) / MM),
        "p_value": p,
        "plausible": bool(described),
        "passed": bool(p >= level and described),
        "at_noise": at_noise,
        "refit": {
            "observed_rms_per_axis_mm": observed_refit / MM,
            "replicate_median_mm": float(np.median(replicates_refit) / MM),
            "replicate_p95_mm": float(np.quantile(replicates_refit, QUANTILE) / MM),
            "p_value": p_refit,
            "passed": bool(p_refit >= level),
            "excess_mean_square_mm2": excess / MM**2,
            "excess_mean_square_after_refit_mm2": excess_refit / MM**2,
            "excess_removed": removed,
            # the share removed, not the refit's pass: with a declared model error a 6-dof refit passes
            # a non-rigid error (a distorted frame) too
            "explains": bool(removed is not None and removed >= registration_share),
            "move": move_report(moves[0], measured),
        },
    }


def _replicated(claim: Claim, rng: np.random.Generator, refit: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """(the statistic of each replicate (m,), and of each after its own registration refit (m,),
    None without `refit`), made a chunk of draws at a time so that memory stays bounded whatever
    the campaign's size."""
    chunk = max(1, CHUNK_VALUES // claim.reference.size)
    replicates, replicates_refit = [], []
    for begin in range(0, len(claim.theta), chunk):
        replicated = claim.replicates(np.arange(begin, min(begin + chunk, len(claim.theta))), rng)
        replicates.append(rms_per_axis(replicated - claim.reference))
        if refit:
            replicates_refit.append(rms_per_axis(refit_residuals(claim.reference, replicated)[0]))
    return np.concatenate(replicates), (np.concatenate(replicates_refit) if refit else None)


def claim_budget(measured, claim: Claim, rng: np.random.Generator, mpe: float | None = None) -> dict:
    """The uncertainty budget of a claim at the validation configurations by Monte Carlo (JCGM 101):
    its replicates (`Claim.parts`, as many draws as fit in CHUNK_VALUES) split by source, each with
    its u per axis (RMS over draws, configurations and axes) and share of the variance (the sources
    are independent, so their variances add, nothing counted twice); the combined u per axis; the
    measurand's 95 % quantile, the 3-D distance |e| pooled over draws and configurations (what a
    measurement by this instrument at a validation configuration differs from the prediction by),
    and the same without the instrument (the calibrated position's own error); and its check on
    rows the fit never saw: the share of the validation rows measured (n, 3) m within it. mpe (m):
    the instrument's stated MPE, given for reference (it bounds the noise the budget already holds).
    JSON-ready, mm."""
    rows = np.arange(min(len(claim.theta), max(1, CHUNK_VALUES // claim.reference.size)))
    parts = claim.parts(rows, rng)
    total = sum(parts.values())
    position = total - parts.get(NOISE, 0.0) - parts.get(FITTED_NOISE, 0.0)
    u = {source: float(np.sqrt(np.mean(part**2))) for source, part in parts.items()}
    variance = sum(v**2 for v in u.values())
    bound = float(np.quantile(np.linalg.norm(total, axis=-1), QUANTILE))
    observed = np.linalg.norm(np.asarray(measured, dtype=float) - claim.reference, axis=-1)
    return {
        "sources": [
            {"source": source, "u_per_axis_mm": value / MM, "share_percent": 100 * value**2 / variance}
            for source, value in u.items()
        ],
        "combined_u_per_axis_mm": float(np.sqrt(np.mean(total**2)) / MM),
        "U95_distance_mm": bound / MM,
        "U95_position_distance_mm": float(np.quantile(np.linalg.norm(position, axis=-1), QUANTILE) / MM),
        "validation_within_U95": float(np.mean(observed <= bound)),
        "validation_rows": int(len(observed)),
        "draws": int(len(rows)),
        "mpe_mm": None if mpe is None else float(mpe) / MM,
        "quantity": "the 3-D distance between a measurement at a validation configuration and the calibration's "
        "prediction there: its 95th percentile over posterior draws and configurations (Monte Carlo, JCGM 101)",
    }


# --------------------------------------------------------------------------- the models' claims


def _noise_draws(sigma, measured, shape, rng: np.random.Generator, tracker: noise.RangeTransverse | None):
    """Noise (m, n, 3) m with std sigma (m,) per draw: isotropic, or the tracker's range/transverse
    shape at the measured points (n, 3) (transverse std k_i sigma about the direction from the head)."""
    z = rng.standard_normal(shape)
    if tracker is not None:
        u = measured / np.linalg.norm(measured, axis=1, keepdims=True)
        along = np.sum(z * u, axis=-1, keepdims=True) * u
        z = along + tracker.ratios(measured)[:, None] * (z - along)
    return np.asarray(sigma, dtype=float)[:, None, None] * z


def _rows(count: int, available: int, rng: np.random.Generator) -> np.ndarray:
    return rng.choice(available, count, replace=available < count)


def _checked_samples(samples: pd.DataFrame, names: Sequence[str], label: str) -> pd.DataFrame:
    require_columns(samples, list(names) + [SIGMA], file=label, of="the posterior samples")
    return samples[list(names) + [SIGMA]].astype(float).reset_index(drop=True)


def paper_claim(
    model: BlockModel,
    laplace: LaplaceReport,
    samples: pd.DataFrame | None,
    count: int,
    rng: np.random.Generator,
    label: str = "",
) -> Claim:
    """The paper's model (registration + zero-offsets, held ones at their value: `blocks.paper_model`)
    at the validation readings: draws from its posterior samples (the default sampler's), or from its
    Laplace approximation when none are given."""
    if samples is not None and not samples.empty:
        table = _checked_samples(samples, model.names, label)
        chosen = table.iloc[_rows(count, len(table), rng)]
        theta, sigma = chosen[list(model.names)].to_numpy(), chosen[SIGMA].to_numpy()
        mean = table[list(model.names)].mean().to_numpy()
        source = "the paper model's posterior samples (default sampler)"
    else:
        laplace.check_names(model.names)
        theta = rng.multivariate_normal(laplace.theta_map, laplace.covariance, count)
        sigma = np.abs(laplace.sigma_map + laplace.sigma_std * rng.standard_normal(count))
        mean = laplace.theta_map
        source = "the paper model's Laplace approximation (no samples given)"
    return Claim(model.predict(mean), model, theta, sigma, (), source)


def loop_model(chain: KinematicChain, data: Readings, marker, t_nr, report: LoopReport) -> BlockModel:
    """The loop closure's final parametric model on some readings: its effects (the residual GP
    apart), its held parameters at their values, its noise shape."""
    table = report.parameters
    held = table[(table["status"].astype(str) != "estimated") & (table["block"] != "noise")]
    effects = tuple(b for b in report.effects_added if b != GP)
    chosen = (report.noise_model or {}).get("chosen")
    shape = None
    if chosen == "range_transverse":
        shape = noise.RangeTransverse(float(report.noise_model["transverse_growth_per_m"]))
    fixed = dict(zip(held["parameter"].astype(str), held["mean"].astype(float)))
    return BlockModel(chain, data, marker, t_nr, effects, fixed, None, shape)


def loop_claim(model: BlockModel, loop: LoopResults, count: int, rng: np.random.Generator, label: str = "") -> Claim:
    """The loop-closed model (`loop_model`) at the validation readings: its MCMC refit's draws (the
    Laplace approximation's diagonal when the refit ran without MCMC), plus its residual GP when it
    added one (mean at the reference; drawn jointly across the readings, its noise std the noise
    when the campaign states none, as `workspace` propagates it)."""
    report, samples = loop.report, loop.samples
    names = list(model.names)
    if samples is not None and not samples.empty:
        table = _checked_samples(samples, names, label)
        chosen = table.iloc[_rows(count, len(table), rng)]
        theta, sigma = chosen[names].to_numpy(), chosen[SIGMA].to_numpy()
        mean = table[names].mean().to_numpy()
        source = "the loop closure's MCMC refit"
    else:
        mode = report.refit["mode"]
        if list(mode["names"]) != names:
            raise InputError("the refit's parameters are not the model's", file=label, key="refit/mode/names")
        mean, std = np.asarray(mode["theta"], dtype=float), np.asarray(mode["std"], dtype=float)
        theta = mean + std * rng.standard_normal((count, len(mean)))
        sigma = np.full(count, float(mode["sigma_mm"]) * MM)
        source = "the loop closure's Laplace approximation (independent parameters; no MCMC samples)"
    reference = model.predict(mean)
    gp = loop_candidate.from_results(loop.gp_rows, report.residual_gp) if GP in report.effects_added else None
    if gp is None:
        return Claim(reference, model, theta, sigma, tuple(report.effects_added), source)
    rotation = np.asarray(report.residual_gp["rotation_robot_to_sensor"], dtype=float)
    correction = gp.mean(model.data.q) @ rotation.T
    return Claim(
        reference + correction,
        model,
        theta,
        np.full(count, gp.hyper.noise_std),
        tuple(report.effects_added),
        source + " with its residual GP",
        lambda count, rng: gp.draws(model.data.q, count, rng) @ rotation.T,
        correction,
    )


# --------------------------------------------------------------------------- verdict and diagnosis


def diagnose(checks: Mapping[str, Mapping]) -> tuple[str, str | None]:
    """(verdict, diagnosis or None) from the loop-closed model's check, the verdict; a failure is
    diagnosed in the order of the module docstring. The paper model's check chooses nothing."""
    loop = checks["loop"]
    if not loop.get("plausible", True):
        return FAIL, IMPLAUSIBLE
    if loop["passed"]:
        return PASS, None
    if loop["refit"]["explains"]:
        return FAIL, MOVED
    return FAIL, NOT_CONFIRMED


def _claim_text(check: Mapping) -> str:
    """What the claim's noise was, in words."""
    if check.get("noise") != INSTRUMENT:
        return "noise: the fitted sigma (the campaign states no noise): the test cannot see what the sigma absorbed"
    declared = check["declared_model_error_mm"]
    return f"noise: the instrument's {check['instrument_rms_per_axis_mm']:.3g} mm" + (
        f" and a declared model error of {declared:.3g} mm per axis" if declared else ""
    )


def _at_noise_text(check: Mapping, level: float) -> str:
    """What the check against the instrument's noise alone says, when the claim declared a model error."""
    alone = check.get("at_noise")
    if not alone or not check.get("declared_model_error_mm"):
        return ""
    verdict = "passes" if alone["passed"] else f"fails (p < {level:g})"
    return (
        f"; against the instrument's noise alone (what a closed loop would claim) it {verdict}, p = "
        f"{alone['p_value']:.3g}: it holds as far as it declared its residual"
        + ("" if alone["passed"] else ", not to the sensor's noise")
    )


def _diagnosis_text(diagnosis: str | None, checks: Mapping, level: float, plausible_mm: float) -> str:
    loop = checks["loop"]
    head = (
        f"validation RMS per axis {loop['observed_rms_per_axis_mm']:.3g} mm against the loop-closed model's claim "
        f"{loop['replicate_median_mm']:.3g} mm (95 %: {loop['replicate_p95_mm']:.3g} mm; {_claim_text(loop)}), "
        f"p = {loop['p_value']:.3g}"
    )
    if diagnosis is None:
        return f"pass: {head} >= {level:g}" + _at_noise_text(loop, level)
    if diagnosis == IMPLAUSIBLE:
        return (
            f"fail: validation RMS per axis {loop['observed_rms_per_axis_mm']:.3g} mm, beyond the "
            f"{plausible_mm:g} mm no calibrated arm leaves: {DIAGNOSES[diagnosis]}"
        )
    text = f"fail: {head} < {level:g}: {DIAGNOSES[diagnosis]}"
    if diagnosis == MOVED:
        move, refit = loop["refit"]["move"], loop["refit"]
        text += (
            f" (the registration refitted on the validation rows moves the readings by "
            f"{move['translation_norm_mm']:.3g} mm and {move['rotation_deg']:.3g} deg, "
            f"{move['displacement_at_centre_norm_mm']:.3g} mm at the points' centre; the refit leaves "
            f"{refit['observed_rms_per_axis_mm']:.3g} mm, p = {refit['p_value']:.3g})"
        )
        if not refit["passed"]:
            text += f"; beyond the move a robot error remains (the refit check fails too, p < {level:g})"
    return text


@dataclass(frozen=True)
class Acceptance:
    """acceptance.json of one sensor. verdict 'pass' | 'fail' (the loop-closed model's check) |
    'not tested' (fewer than MIN_VALIDATION_ROWS measured validation rows: checks empty) |
    'cannot test' (fewer distinct configurations than `configurations_needed`: the checks are made
    and kept, never a pass); configurations: `configurations_report` (None when not tested);
    diagnosis: None or one of DIAGNOSES, diagnosis_text its sentence with the numbers; move: the
    registration refit's move (mm, deg) when the diagnosis is a moved sensor, else None; checks:
    {'loop', 'paper': `check`}; level, registration_share, plausible_residual_mm, draws: the
    settings; validation_rows: rows used; gross_errors_left_out: validation rows flagged by the
    gross-error screen and left out; warnings: plain text; budget: the loop-closed claim's
    uncertainty budget (`claim_budget`; None when not tested); source: the file it was read from
    (not written)."""

    sensor: str
    verdict: str
    diagnosis: str | None
    diagnosis_text: str
    move: Mapping | None
    checks: Mapping[str, Mapping]
    level: float
    registration_share: float
    plausible_residual_mm: float
    draws: int
    validation_rows: int
    gross_errors_left_out: tuple[int, ...]
    warnings: tuple[str, ...]
    budget: Mapping | None = None
    configurations: Mapping | None = None
    statistic: str = STATISTIC
    campaign: str | None = None
    source: str = field(default="acceptance.json", compare=False)

    @property
    def passed(self) -> bool:
        return self.verdict == PASS

    def to_json(self) -> dict:
        out = {}
        for f in fields(self):
            if f.name == "source":
                continue
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out

    def write(self, path):
        """Write acceptance.json (`files.write_json`); returns its path."""
        return write_json(path, self.to_json())

    @classmethod
    def of(cls, content: Mapping, source: str = "acceptance.json") -> Acceptance:
        """From the JSON content; a missing key is an InputError naming the file and the key."""
        get = report_reader(content, source, "missing in the acceptance report")
        values = {}
        for f in fields(cls):
            if f.name == "source":
                continue
            # a file written before the configurations were counted has none: the certificate then
            # clusters by pose alone
            value = content.get(f.name) if f.name == "configurations" else get(f.name)
            values[f.name] = tuple(value) if f.name in ("gross_errors_left_out", "warnings") else value
        if values["verdict"] not in VERDICTS:
            raise InputError(f"verdict must be one of {', '.join(map(repr, VERDICTS))}", file=source, key="verdict")
        return cls(**values, source=source)

    @classmethod
    def read(cls, path) -> Acceptance:
        return cls.of(read_json(path), source=str(path))


def _untested(rows: int) -> tuple[str, dict]:
    """(the diagnosis text, the Acceptance fields) of a campaign with fewer than MIN_VALIDATION_ROWS
    measured validation rows: the certificate says the calibration is untested, every other result
    stands."""
    text = (
        f"not tested: {rows} measured validation rows (at least {MIN_VALIDATION_ROWS} needed); "
        "measure a validation set to accept this calibration"
    )
    return text, {
        "verdict": UNTESTED,
        "diagnosis": None,
        "move": None,
        "checks": {},
        "budget": None,
        "configurations": None,
    }


def distinct_configurations(q, tolerance: float = SAME_CONFIGURATION) -> np.ndarray:
    """(n,) labels 0..G-1 of the distinct configurations of joint readings q (n, N) rad, numbered
    in the order of their first row: a row joins the first configuration whose first row's readings
    it matches to within `tolerance` (rad) in every joint, else it starts one. Leader clustering: a
    configuration spans at most twice the tolerance, so a slow sweep is never chained into one."""
    q = np.asarray(q, dtype=float).reshape(len(q), -1)
    if not len(q):
        return np.zeros(0, dtype=int)
    unique, first, inverse = np.unique(q, axis=0, return_index=True, return_inverse=True)
    leaders = np.empty_like(unique)
    label = np.empty(len(unique), dtype=int)
    count = 0
    for u in np.argsort(first):  # each distinct reading in the order of its first row
        hit = np.flatnonzero(np.all(np.abs(leaders[:count] - unique[u]) < tolerance, axis=1))
        if hit.size:
            label[u] = hit[0]
        else:
            leaders[count], label[u] = unique[u], count
            count += 1
    return label[inverse.ravel()]


def configurations_needed(parameters: int) -> int:
    """The fewest distinct configurations that test a calibration of `parameters` free parameters
    (the paper model's: registration and zero-offsets): each gives three numbers, and fewer numbers
    than parameters leave some combination of them unseen whatever the rows (the validation
    Jacobian has a null space); never fewer than MIN_CONFIGURATIONS, which the refit needs."""
    return max(MIN_CONFIGURATIONS, -(-int(parameters) // 3))


def repeats_report(residuals, groups, rows) -> dict | None:
    """ISO 9283 pose repeatability of the configurations measured more than once (`iso9283`):
    residuals (n, 3) m measured minus predicted, groups (n,) the configuration of each row
    (`distinct_configurations`), rows (n,) their table rows. JSON-ready, mm; None when nothing
    repeats. RP = l_bar + 3 S_l holds the sensor's noise and the robot's repeatability together."""
    from .iso9283 import pose_characteristics

    poses = pose_characteristics(residuals, groups)
    repeated = poses[poses["cycles"] > 1]
    if repeated.empty:
        return None
    _, first = np.unique(np.asarray(groups), return_index=True)
    first_row = dict(zip(poses["group"].tolist(), np.asarray(rows)[first].tolist()))
    return {
        "configurations": int(len(repeated)),
        "cycles": int(repeated["cycles"].sum()),
        "cycles_min": int(repeated["cycles"].min()),
        "cycles_max": int(repeated["cycles"].max()),
        "RP_mean_mm": float(repeated["RP"].mean() / MM),
        "RP_max_mm": float(repeated["RP"].max() / MM),
        "per_configuration": [
            {
                "first_row": int(first_row[r["group"]]),
                "cycles": int(r["cycles"]),
                "AP_mm": float(r["AP"] / MM),
                "RP_mm": float(r["RP"] / MM),
            }
            for _, r in repeated.iterrows()
        ],
    }


def configurations_report(data: Readings, reference, parameters: int) -> dict:
    """What the validation set can test (module docstring): its distinct configurations
    (`distinct_configurations`) against those a calibration of `parameters` free parameters needs
    (`configurations_needed`), each used table row's configuration, and the repeatability of the
    repeated ones (`repeats_report`, residuals against the prediction `reference` (n, 3) m).
    JSON-ready."""
    groups = distinct_configurations(data.q)
    distinct, needed = int(groups.max()) + 1 if len(groups) else 0, configurations_needed(parameters)
    return {
        "distinct": distinct,
        "rows": int(len(groups)),
        "needed": needed,
        "parameters": int(parameters),
        "tolerance_deg": SAME_CONFIGURATION / DEG,
        "tests": bool(distinct >= needed),
        "table_rows": [int(r) for r in data.rows],
        "configuration_of_row": groups.tolist(),
        "repeats": repeats_report(np.asarray(data.measured) - np.asarray(reference), groups, data.rows),
    }


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def repeats_text(repeats: Mapping | None) -> str:
    """The ISO 9283 repeatability of the repeated configurations in words ('' when none repeats)."""
    if not repeats:
        return ""
    cycles = (
        f"{repeats['cycles_min']} cycles"
        if repeats["cycles_min"] == repeats["cycles_max"]
        else f"{repeats['cycles_min']} to {repeats['cycles_max']} cycles"
    )
    rp = (
        f"RP {repeats['RP_max_mm']:.2g} mm"
        if repeats["configurations"] == 1
        else f"RP {repeats['RP_mean_mm']:.2g} mm mean, {repeats['RP_max_mm']:.2g} mm at most"
    )
    return (
        f"ISO 9283 pose repeatability of {_plural(repeats['configurations'], 'repeated configuration')} "
        f"({cycles} each): {rp} (the sensor's noise and the robot's repeatability together)"
    )


def _cannot_test(configurations: Mapping, loop: Mapping, level: float) -> tuple[str, str]:
    """(the verdict's text, the warning) of a validation set with fewer distinct configurations than
    a test needs: no pass; what the check at them says and the repeats' repeatability."""
    distinct, rows, needed = configurations["distinct"], configurations["rows"], configurations["needed"]
    text = (
        f"cannot test: {_plural(distinct, 'distinct configuration')} of {rows} validation rows "
        f"(at least {needed} needed)"
    )
    result = (
        f"the check at {'it' if distinct == 1 else 'them'} passes (p = {loop['p_value']:.3g}), a check of the "
        "noise there, not of the calibration"
        if loop["passed"]
        else f"the check at {'it' if distinct == 1 else 'them'} fails (validation RMS per axis "
        f"{loop['observed_rms_per_axis_mm']:.3g} mm, p = {loop['p_value']:.3g} < {level:g}): the calibration or "
        "the set-up is off there, and so few configurations cannot tell which"
    )
    repeats = repeats_text(configurations.get("repeats"))
    warning = (
        f"acceptance test {text}: the validation set cannot test the calibration, so it gives no acceptance pass "
        f"(rows whose joint readings agree to {configurations['tolerance_deg']:g} deg in every joint are one "
        f"configuration; {configurations['parameters']} free parameters, three numbers per configuration); "
        f"{result}" + (f"; {repeats}" if repeats else "") + f"; measure at least {needed} configurations spread "
        "over the joint ranges to accept this calibration"
    )
    return text, warning


def _warnings(checks: Mapping, diagnosis: str | None, effects, flagged, level: float, plausible_mm: float) -> list[str]:
    """What the certificate must say of the checks: the diagnosis of a failure, a claim that used
    the fitted sigma, a loop-closed model that validates worse than the paper's (both numbers; the
    loop-closed model stays the recommended one), and the validation rows left out as gross errors."""
    warnings = []
    loop, paper = checks["loop"], checks["paper"]
    if diagnosis is not None:
        warnings.append(
            f"acceptance test on the validation set: {_diagnosis_text(diagnosis, checks, level, plausible_mm)}"
        )
    if loop.get("noise") != INSTRUMENT:
        warnings.append(
            "the acceptance test's noise is the fitted sigma: the campaign states no sensor noise, point std or "
            "repeats, so the test cannot fail a model whose missing effect the sigma absorbed"
        )
    if effects and loop["observed_rms_per_axis_mm"] > paper["observed_rms_per_axis_mm"]:
        warnings.append(
            f"the loop-closed model ({', '.join(effects)}) validates worse than the paper's "
            f"({loop['observed_rms_per_axis_mm']:.3g} against {paper['observed_rms_per_axis_mm']:.3g} mm RMS per "
            f"axis; the paper's model {'passes' if paper['passed'] else 'fails'} its own check, p = "
            f"{paper['p_value']:.3g})"
        )
    if flagged:
        warnings.append(
            f"{len(flagged)} validation rows flagged as gross errors left out of the check (rows {flagged})"
        )
    return warnings


def instrument_noise(sensor, rows) -> np.ndarray | None:
    """(len(rows), 3) m: the instrument's noise std per reading and axis at table rows: the
    per-point std columns where the table has them, else the sensor's stated noise; None without
    either."""
    point_std = sensor.point_std(rows)
    if point_std is not None:
        return point_std
    return None if sensor.noise is None else np.full((len(rows), 3), float(sensor.noise))


def _judged(
    data: Readings, claims: Mapping[str, Claim], checks: Mapping, effects, flagged, level: float, plausible_mm: float
) -> tuple[str, list[str], dict]:
    """(the verdict's text, the warnings, the Acceptance fields of the verdict but the budget) of
    the checks made on the validation readings `data`: the loop-closed model's check diagnosed
    (`diagnose`), or CANNOT_TEST when the set has fewer distinct configurations than the paper
    model's free parameters need (`configurations_report`): never a pass, the checks kept."""
    configurations = configurations_report(data, claims["loop"].reference, claims["paper"].theta.shape[1])
    effects = list(effects)
    if configurations["tests"]:
        result, diagnosis = diagnose(checks)
        text = _diagnosis_text(diagnosis, checks, level, plausible_mm)
        warnings = _warnings(checks, diagnosis, effects, flagged, level, plausible_mm)
    else:
        result, diagnosis = CANNOT_TEST, None
        text, flag = _cannot_test(configurations, checks["loop"], level)
        warnings = [flag, *_warnings(checks, None, effects, flagged, level, plausible_mm)]
    verdict = {
        "verdict": result,
        "diagnosis": diagnosis,
        "move": checks["loop"]["refit"]["move"] if diagnosis == MOVED else None,
        "checks": checks,
        "configurations": configurations,
    }
    return text, warnings, verdict


def acceptance_stage(
    campaign,
    sensor: str,
    t_nr,
    laplace: LaplaceReport,
    paper_samples: pd.DataFrame | None,
    loop: LoopResults,
    rng: np.random.Generator,
    settings: Mapping,
) -> Acceptance:
    """The acceptance check of one sensor of a campaign (module docstring). t_nr (4, 4): the fit's
    initial registration (registration.json); laplace: the paper's fit; paper_samples: its default
    sampler's samples (None: its Laplace approximation); loop: the loop closure's report, MCMC
    samples and residual-GP training rows; rng draws the posterior rows and the noise; settings: the
    config's `acceptance` section: level, the p-value below which a model fails; draws, replicates
    per model; registration_share, the share of the excess a refit registration must remove to
    explain it; plausible_residual_mm, the validation RMS per axis beyond which a model does not
    describe the arm."""
    level, draws = float(settings["level"]), int(settings["draws"])
    registration_share = float(settings["registration_share"])
    plausible_mm = float(settings["plausible_residual_mm"])
    chain, measured, report = campaign.chain, campaign.sensors[sensor], loop.report
    flagged = sorted(int(r) for r in report.gross_errors["validation"])
    model_settings = ModelSettings(
        payload_mass=report.payload_mass,
        payload_com=report.payload_com,
        drift_column=(report.settings or {}).get("drift_column"),
        harmonic_orders=report.harmonic_orders,
    )
    data = readings(chain, measured, "validation", model_settings, flagged)
    if len(data.rows) < MIN_VALIDATION_ROWS:
        text, verdict = _untested(len(data.rows))
        warnings = [f"acceptance test {text}"]
    else:
        label = f"{campaign.name}/{sensor}"
        # the paper's model on the validation readings, their per-point weights with them
        paper = blocks.paper_model(chain, data.q, data.measured, measured.marker, t_nr, laplace.held, data.rows)
        claims = {
            "loop": loop_claim(loop_model(chain, data, measured.marker, t_nr, report), loop, draws, rng, label),
            "paper": paper_claim(paper.on(data), laplace, paper_samples, draws, rng, label),
        }
        instrument = instrument_noise(measured, data.rows)
        for model in MODELS:
            declared = report.declared_model_error(model)
            if instrument is not None and declared is not None:
                claims[model] = dataclasses.replace(claims[model], instrument=instrument, declared=declared)
        checks = {m: check(data.measured, claims[m], level, registration_share, rng, plausible_mm * MM) for m in MODELS}
        text, warnings, verdict = _judged(data, claims, checks, report.effects_added, flagged, level, plausible_mm)
        verdict["budget"] = {
            **claim_budget(data.measured, claims["loop"], rng, measured.mpe),
            "validation_configurations": verdict["configurations"]["distinct"],
            "validation_tests": verdict["configurations"]["tests"],
        }
    copies = measured.validation_copies()
    if len(copies):
        warnings.append(
            f"validation set: {len(copies)} of its rows repeat optimization rows bit for bit (joint readings "
            f"and measured position; {format_rows(copies)}, 0-based): they test the fit on data "
            "it saw, so the acceptance test and the errors after calibration flatter it"
        )
    return Acceptance(
        sensor=measured.name,
        diagnosis_text=text,
        level=level,
        registration_share=registration_share,
        plausible_residual_mm=plausible_mm,
        draws=draws,
        validation_rows=int(len(data.rows)),
        gross_errors_left_out=tuple(flagged),
        warnings=tuple(warnings),
        campaign=campaign.name,
        **verdict,
    )
