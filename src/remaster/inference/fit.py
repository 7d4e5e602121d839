"""From one sensor's campaign data to a posterior ready for sampling (paper, section Optimization).

1. Initial registration T_NR: the paper's three-point method on three measured configurations
   of the optimization set chosen far apart (nominal forward kinematics gives their robot-frame
   positions); a least-squares (Kabsch) registration over every point is reported beside it.
2. Identifiability: the Jacobian of the full model at zero corrections; each undetermined
   combination gets one parameter held at the controller's value, by the same unit-free test the
   Laplace fit applies, so that the fit cannot stop on a combination the analysis passed
   (`remaster.inference.identifiability`); laplace.json states each held parameter and the
   combination it stood for.
3. The posterior over the free parameters and sigma, as a `PosteriorTarget` that every sampler
   takes.
Points whose marker was not seen are excluded from the fit and listed.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

from .. import diagnostics, spatial
from ..campaigns.campaign import Campaign, SensorData
from ..errors import InputError, report_reader
from ..files import read_json
from ..robot import gravity, registration
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..spatial import transform_points
from . import identifiability, metrics
from .blocks import BlockModel, paper_model
from .least_squares import LaplaceResult, least_squares_laplace, least_squares_mode
from .model import SIGMA, display_scale, display_unit
from .readings import orientation_fields
from .sampling.chains import run_chains, run_emcee
from .sampling.metropolis import metropolis_adaptive, metropolis_paper
from .sampling.target import Chain

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Registration:
    """Initial sensor <- robot transform and how it was obtained. Rows are 0-based rows of the
    sensor table; RMS values are per-axis residuals (m) over the set's measured points."""

    t_nr: np.ndarray
    rows: tuple[int, int, int]
    kabsch_t_nr: np.ndarray
    three_point_rms: float
    kabsch_rms: float

    @classmethod
    def of(cls, content: Mapping, source: str = "registration.json") -> Registration:
        """From the JSON content of `report()`; a missing key is an InputError naming the file and the key."""
        get = report_reader(content, source, "missing in the registration report")
        return cls(
            t_nr=np.asarray(get("T_NR"), dtype=float),
            rows=tuple(int(r) for r in get("rows")),
            kabsch_t_nr=np.asarray(get("kabsch_T_NR"), dtype=float),
            three_point_rms=float(get("three_point_rms_mm")) * 1e-3,
            kabsch_rms=float(get("kabsch_rms_mm")) * 1e-3,
        )

    @classmethod
    def read(cls, path) -> Registration:
        """From registration.json; InputError naming the file, and the key when one is missing."""
        return cls.of(read_json(path), source=str(path))

    def report(self) -> dict:
        rotation_difference = self.t_nr[:3, :3].T @ self.kabsch_t_nr[:3, :3]
        angle = np.degrees(spatial.rotation_angle(rotation_difference))
        return {
            "method": "three-point (paper)",
            "rows": list(self.rows),
            "T_NR": self.t_nr.tolist(),
            "kabsch_T_NR": self.kabsch_t_nr.tolist(),
            "three_point_rms_mm": self.three_point_rms * 1e3,
            "kabsch_rms_mm": self.kabsch_rms * 1e3,
            "three_point_vs_kabsch": {
                "translation_mm": float(np.linalg.norm(self.t_nr[:3, 3] - self.kabsch_t_nr[:3, 3]) * 1e3),
                "rotation_deg": float(angle),
            },
        }


def register(chain: KinematicChain, sensor: SensorData, set_name: str = "optimization") -> Registration:
    """The paper's three-point registration from three far-apart measured configurations of the
    set, with a Kabsch registration over all of them for comparison."""
    rows = sensor.measured_rows(set_name)
    q = sensor.table[list(sensor.joint_columns)].to_numpy(float)[rows]
    measured = sensor.table[["x", "y", "z"]].to_numpy(float)[rows]
    robot = ForwardKinematics(chain, q).points(sensor.marker)
    triple = registration.spread_out_triple(measured)
    three = registration.three_point(robot[triple], measured[triple])
    kabsch = registration.kabsch(robot, measured)

    def rms(t_nr):
        return float(metrics.rms_per_axis(transform_points(t_nr, robot) - measured))

    return Registration(three, tuple(int(r) for r in rows[triple]), kabsch, rms(three), rms(kabsch))


def build_model(
    chain: KinematicChain,
    sensor: SensorData,
    t_nr,
    set_name: str = "optimization",
    exclude=(),
    orientation: bool = True,
    orientation_weight: float | None = None,
):
    """(model with undetermined parameters held, identifiability analysis, rows without a
    measurement). `exclude`: further table rows left out (flagged outliers); orientation: a
    full-pose probe's orientations enter the likelihood beside its points (False: points alone),
    weighed by `orientation_weight` (m/rad; None: the stated noises' ratio, `orientation_fields`)."""
    rows = np.setdiff1d(sensor.measured_rows(set_name), np.asarray(exclude, dtype=int))
    q = sensor.table[list(sensor.joint_columns)].to_numpy(float)[rows]
    measured = sensor.table[["x", "y", "z"]].to_numpy(float)[rows]
    orientation = orientation_fields(sensor, rows) if orientation else {}
    if orientation and orientation_weight is not None:
        orientation["orientation_weight"] = float(orientation_weight)
    analysis = identified(paper_model(chain, q, measured, sensor.marker, t_nr, orientation=orientation))
    model = paper_model(
        chain, q, measured, sensor.marker, t_nr, fixed=analysis.held, table_rows=rows, orientation=orientation
    )
    excluded = np.flatnonzero(sensor.set_mask(set_name) & ~sensor.measured_mask)
    return model, analysis, excluded


def identified(full: BlockModel) -> identifiability.Identifiability:
    """The identifiability analysis of a model with every parameter free, by the Laplace fit's own
    tests at the fit's own optimum: the singular-value test at zero corrections holds what the data
    cannot see at all; the least-squares mode of the rest (the Laplace fit's, `least_squares_mode`)
    gives the optimum and sigma = sqrt(SS / (k - P)) (the Laplace covariance's); there both tests
    run again (`identifiability.analyse`): the singular values, and the std of each zero-offset
    against the controller marks' tolerance (STD_BOUND). The fit that follows on what is left free
    tests at that same optimum, so it cannot stop on what the analysis passed."""
    structural = identifiability.analyse(full)
    reduced = BlockModel(full.chain, full.data, full.marker, full.t_nr, (), structural.held)
    target = PosteriorTarget(reduced)
    scale = reduced.scale
    mode = least_squares_mode(target.residuals, np.zeros(len(reduced.names)), scale)
    residuals = target.residuals(mode.x)
    dof = residuals.size - len(reduced.names)
    if dof <= 0:  # too few data for a sigma: the singular-value test alone (the fit says why)
        return structural
    sigma = math.sqrt(float(residuals @ residuals) / dof)
    return identifiability.analyse(full, theta=reduced.full(mode.x), sigma=sigma)


BALANCE_ROUNDS = 20  # at most this many refits while balancing a probe's orientations against its points
BALANCE_TOLERANCE = 1e-3  # relative change of the weight at which the balance has settled


def balanced_orientation(model: BlockModel) -> BlockModel:
    """The model with a full-pose probe's orientations weighed by the fit's own residuals: weight =
    RMS position residual / RMS orientation residual per component at the least-squares fit,
    refitted from the readings' weight (the stated noises' ratio) until it settles. One sigma is
    then the noise of both: where the zero-offset model lacks an effect of the positions (compliance,
    link geometry), the stated ratio would let the orientations' smaller residuals pull it below the
    positions' own, and every std with it. A model without orientations is returned as it is."""
    if not model.has_orientation:
        return model
    for _ in range(BALANCE_ROUNDS):
        theta = laplace_fit(model).theta_map
        positions = float(np.sqrt(np.mean(model.whitened(model.residuals(theta)) ** 2)))
        orientations = float(np.sqrt(np.mean(model.orientation_residuals(theta) ** 2)))
        weight = positions / max(orientations, 1e-300)
        previous = model.data.orientation_weight
        model = model.on(replace(model.data, orientation_weight=weight))
        if abs(weight - previous) <= BALANCE_TOLERANCE * previous:
            break
    return model


def flag_outliers(model: BlockModel, alpha: float) -> np.ndarray:
    """Table rows of gross measurement errors (a laser tracker's re-acquisition glitch, a swapped
    marker): points whose residual after a robust (Cauchy-loss) least-squares fit is farther
    from the model than an isotropic Gaussian of the robust scale sigma_r (1.4826 MAD of the
    residual components) allows for any of the n points at family-wise level `alpha`:
    |E_i| > sigma_r sqrt(chi2_3 quantile at 1 - alpha / n) (Bonferroni). The robust loss keeps one
    glitch of several mm from dragging the fit towards it.

    Provisional: judged by the zero-offset model, whose residuals are not Gaussian where it lacks an
    effect, so it flags good rows there and can miss a glitch behind the model's error. Its rows
    stay out of the paper model's fit only; the loop closure screens every row again with its final
    model (`remaster.loop.gross`), and that screen's rows are the gross errors listed."""
    import scipy.optimize
    import scipy.special

    scale = np.array([display_scale(n) for n in model.names])
    start = np.zeros(len(model.names))
    first = scipy.optimize.least_squares(lambda t: model.residuals(t).ravel(), start, x_scale=scale)
    spread = 1.4826 * np.median(np.abs(first.fun))
    robust = scipy.optimize.least_squares(
        lambda t: model.residuals(t).ravel(), first.x, x_scale=scale, loss="cauchy", f_scale=max(spread, 1e-9)
    )
    residual = np.abs(model.residuals(robust.x))
    sigma_r = 1.4826 * np.median(residual)
    threshold = math.sqrt(scipy.special.chdtri(3, alpha / model.n_points))  # chi2(3).isf, without scipy.stats' import
    far = np.linalg.norm(residual, axis=1) > threshold * sigma_r
    if 3 * (model.n_points - int(far.sum())) <= len(model.names) + 1:
        # a set barely larger than the fit needs is fitted almost exactly, so the robust scale is
        # near 0 and good rows look far; leaving them out would leave the fit undetermined (a
        # ValueError naming no row): keep every row, the loop closure's screen judges them again
        log.warning(
            "%d of %d points look like gross errors, but the fit without them would be undetermined "
            "(%d parameters and sigma): too few data to screen, every point kept (rows %s)",
            int(far.sum()),
            model.n_points,
            len(model.names),
            model.data.rows[far].tolist(),
        )
        return model.data.rows[:0]
    return model.data.rows[far]


POINTS_PER_CALL = 2**20  # predicted points held at once by a stacked evaluation (24 MB per array)


@dataclass(frozen=True)
class PosteriorTarget:
    """The log-posterior of a model over (free parameters..., noise.sigma), for the samplers."""

    model: BlockModel

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.names + (SIGMA,)

    @property
    def scale(self) -> np.ndarray:
        """Step units: the model's own (extended models have their own units), sigma in mm."""
        return np.append(self.model.scale, display_scale(SIGMA))

    def log_prob(self, theta) -> float:
        theta = np.asarray(theta, dtype=float)
        return float(self.model.log_posterior(theta[:-1], theta[-1]))

    @property
    def walk_block(self):
        """The model's compiled random-walk block (`BlockModel.metropolis_block`) when it has one
        (the paper's model), else None: the samplers then step in Python."""
        return self.model.metropolis_block if self.model.compiled_posterior else None

    def log_prob_many(self, thetas) -> np.ndarray:
        """Log-posterior (m,) of m vectors (m, P + 1), a slice of at most POINTS_PER_CALL / n
        vectors at a time: each vector's predictions (n, 3) are held at once, so a sampler's
        batch of thousands of proposals stays within memory on a campaign of any size."""
        thetas = np.asarray(thetas, dtype=float)
        size = max(1, POINTS_PER_CALL // max(self.model.n_points, 1))
        return np.concatenate(
            [
                self.model.log_posterior(part[:, :-1], part[:, -1])
                for part in (thetas[k : k + size] for k in range(0, len(thetas), size))
            ]
            or [np.empty(0)]
        )

    def residuals(self, theta_model) -> np.ndarray:
        """Residual vector (3n,) of the model parameters (sigma excluded), for least squares; a
        full-pose probe's weighted orientation residuals follow (`BlockModel.weighted_residuals`)."""
        if self.model.has_orientation:
            return self.model.weighted_residuals(theta_model).ravel()
        return self.model.residuals(theta_model).ravel()


@dataclass(frozen=True)
class SigmaMarginalTarget:
    """The posterior of a model's free parameters with sigma integrated out, for the samplers.

    Under Jeffreys' prior the log-posterior is -(N + 2) log sigma - SS(theta) / (2 sigma^2) + log
    prior(theta), N = 3n, so sigma integrates out in closed form: log p(theta) = -(N + 1) / 2
    log SS(theta) + log prior(theta), and given theta, SS / sigma^2 is chi-square with N + 1 degrees
    of freedom. Sampling theta alone removes the coupling of sigma with theta's scale (the joint
    mode's sigma is sqrt(N / (N + 1)) times its marginal's, with theta's spread in proportion),
    which a Laplace approximation about the joint mode misses; `with_sigma` then draws sigma exactly."""

    model: BlockModel

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.names

    @property
    def scale(self) -> np.ndarray:
        return self.model.scale

    def log_prob(self, theta) -> float:
        return float(self.log_prob_many(np.asarray(theta, dtype=float)[None, :])[0])

    def log_prob_many(self, thetas) -> np.ndarray:
        """Log marginal posterior (m,) of m vectors (m, P), up to a constant, a slice at a time
        (`PosteriorTarget.log_prob_many`)."""
        thetas = np.asarray(thetas, dtype=float)
        size = max(1, POINTS_PER_CALL // max(self.model.n_points, 1))
        power = 0.5 * (3 * self.model.n_rows + 1)
        parts = []
        for k in range(0, len(thetas), size):
            part = thetas[k : k + size]
            with np.errstate(divide="ignore"):
                value = -power * np.log(self.model.sum_squares(part))
            parts.append(value + self.model.log_prior(part))
        return np.concatenate(parts) if parts else np.empty(0)

    def with_sigma(self, chain: Chain, rng: np.random.Generator) -> Chain:
        """`chain` over theta (the model's own parameters) with sigma drawn from p(sigma | theta) for
        each sample, appended as the last parameter, and the joint log-posterior as log_prob."""
        theta = chain.samples
        energy = self.model.sum_squares(theta)
        sigma = np.sqrt(energy / rng.chisquare(3 * self.model.n_rows + 1, len(theta)))
        return replace(
            chain,
            samples=np.column_stack([theta, sigma]),
            log_prob=self.model.log_posterior(theta, sigma),
            names=self.names + (SIGMA,),
        )


# --------------------------------------------------------------------------- fitting

METHODS = ("paper", "default", "emcee")
METHOD_LABELS = {
    "paper": "Metropolis (paper)",
    "default": "adaptive Metropolis",
    "emcee": "emcee",
    "laplace": "least squares + Laplace",
}


def laplace_fit(model: BlockModel) -> LaplaceResult:
    """Least-squares MAP of the model parameters from zero corrections, with its Laplace covariance."""
    target = PosteriorTarget(model)
    return least_squares_laplace(target.residuals, np.zeros(len(model.names)), model.scale, names=model.names)


def laplace_report(
    result: LaplaceResult,
    analysis: identifiability.Identifiability,
    excluded_rows,
    outlier_rows=(),
    model: BlockModel | None = None,
) -> dict:
    """JSON-ready: the MAP, covariance and sigma (SI), the identifiability analysis, the rows
    left out (marker not seen; flagged as outliers), the number of points fitted, and the tool
    the chain's URDF carries (`gravity.tool_report`: the loop closure's gravity torques take it
    instead of the configured payload; None when it carries none or no model is given)."""
    return {
        "names": list(result.names),
        "theta_map": result.theta_map.tolist(),
        "covariance": result.covariance.tolist(),
        "std": result.std.tolist(),
        "sigma_map": result.sigma_map,
        "sigma_mean": result.sigma_mean,
        "sigma_std": result.sigma_std,
        "sum_squares": 2.0 * result.cost,
        "n_residuals": result.n_residuals,
        "jacobian_singular_values_step_units": result.jacobian_singular_values.tolist(),
        "identifiability": analysis.report(),
        "excluded_rows_marker_not_seen": [int(r) for r in excluded_rows],
        "excluded_rows_outliers": [int(r) for r in outlier_rows],
        "points_fitted": None if model is None else int(model.n_points),
        "urdf_tool": None if model is None else gravity.tool_report(model.chain),
    }


def orientation_added(
    result: LaplaceResult,
    analysis: identifiability.Identifiability,
    points: LaplaceResult,
    points_analysis: identifiability.Identifiability,
    model: BlockModel,
) -> dict:
    """What a full-pose probe's orientations added to the zero-offset fit, JSON-ready: the rows
    fitted with one, their weight (m/rad, `balanced_orientation`), the parameters held with points alone that the orientations determine, each
    fit's sigma and parameter stds (`points`, `points_analysis`: the same rows' points alone), and
    `information_ratio`: each std with the orientations over its std from the points alone at one
    sigma (std / sigma of each fit), the data's part; the stds' own ratio also carries the change of
    the one sigma."""
    points_std = dict(zip(points.names, points.std.tolist()))
    sigmas = result.sigma_map / points.sigma_map
    return {
        "orientations_fitted": int(model.n_orientations),
        "weight_m_per_rad": float(model.data.orientation_weight),
        "held_with_orientation": sorted(analysis.held),
        "held_with_points_alone": sorted(points_analysis.held),
        "determined_only_with_orientation": sorted(set(points_analysis.held) - set(analysis.held)),
        "sigma_with_orientation_m": float(result.sigma_map),
        "sigma_with_points_alone_m": float(points.sigma_map),
        "std_with_orientation": dict(zip(result.names, result.std.tolist())),
        "std_with_points_alone": points_std,
        "information_ratio": {
            n: float(s / points_std[n] / sigmas) for n, s in zip(result.names, result.std) if n in points_std
        },
    }


@dataclass(frozen=True, eq=False)
class LaplaceReport:
    """The paper model's Laplace fit of one sensor as the later stages read it (`laplace.json`,
    written by `laplace_report`; read by `LaplaceReport.read`). names (P,) free parameters;
    theta_map, std (P,) and covariance (P, P) SI; sigma_map, sigma_mean, sigma_std (m);
    parameters: every parameter in order, held ones included; held: {name: value} held at the
    controller's value; null_directions: the data's blind combinations ({name: weight} each);
    outlier_rows and marker_not_seen_rows: table rows left out of the fit;
    points_fitted (None when the report was made without the model); held_statements: one sentence
    per held parameter, saying what the data cannot tell apart; orientation: what a full-pose
    probe's orientations added (`orientation_added`), None for points alone; held_reasons: {held
    name: 'not identifiable' or 'not determined: std ...'} (`Identifiability.reasons`)."""

    names: tuple[str, ...]
    theta_map: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    sigma_map: float
    sigma_mean: float
    sigma_std: float
    parameters: tuple[str, ...]
    held: dict[str, float]
    null_directions: tuple[dict[str, float], ...]
    outlier_rows: tuple[int, ...]
    marker_not_seen_rows: tuple[int, ...]
    points_fitted: int | None
    held_statements: tuple[str, ...] = ()
    orientation: dict | None = None
    held_reasons: Mapping[str, str] | None = None

    @classmethod
    def of(cls, content: Mapping, source: str = "laplace.json") -> LaplaceReport:
        """From the JSON content; a missing key is an InputError naming the file and the key."""
        get = report_reader(content, source, "missing in the Laplace report")
        return cls(
            names=tuple(get("names")),
            theta_map=np.asarray(get("theta_map"), dtype=float),
            std=np.asarray(get("std"), dtype=float),
            covariance=np.asarray(get("covariance"), dtype=float),
            sigma_map=float(get("sigma_map")),
            sigma_mean=float(get("sigma_mean")),
            sigma_std=float(get("sigma_std")),
            parameters=tuple(get("identifiability", "parameters")),
            held={n: float(v) for n, v in get("identifiability", "held_at_controller_value").items()},
            null_directions=tuple(dict(d) for d in get("identifiability", "null_directions")),
            outlier_rows=tuple(int(r) for r in get("excluded_rows_outliers")),
            marker_not_seen_rows=tuple(int(r) for r in get("excluded_rows_marker_not_seen")),
            points_fitted=None if get("points_fitted") is None else int(get("points_fitted")),
            held_statements=tuple(str(x) for x in get("identifiability", "statements")),
            orientation=content.get("orientation"),
            held_reasons=dict(get("identifiability").get("held_reasons") or {}),
        )

    @classmethod
    def read(cls, path) -> LaplaceReport:
        """From laplace.json; InputError naming the file, and the key when one is missing."""
        return cls.of(read_json(path), source=str(path))

    @property
    def orientation_weight(self) -> float | None:
        """The weight (m/rad) the fit gave a full-pose probe's orientations (`balanced_orientation`),
        None for points alone: every later stage that rebuilds the model takes it."""
        return None if not self.orientation else float(self.orientation["weight_m_per_rad"])

    @property
    def held_with_points_alone(self) -> dict[str, float]:
        """{name: value} held by a model of the points alone (the loop closure's): `held`, plus what a
        full-pose probe's orientations determined and the points alone do not, held at this fit's
        value (the points cannot move it; the calibration's outputs then carry it)."""
        if not self.orientation:
            return dict(self.held)
        estimate = dict(zip(self.names, self.theta_map.tolist()))
        return {**{n: estimate.get(n, 0.0) for n in self.orientation["held_with_points_alone"]}, **self.held}

    def check_names(self, names) -> None:
        """The fitted model's free parameters must be the report's: else the report belongs to
        another model (another campaign, or the fit has changed since)."""
        if tuple(names) != self.names:
            raise ValueError(f"the Laplace fit's parameters {list(self.names)} are not the model's {list(names)}")

    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """(start (P + 1,), covariance (P + 1, P + 1)) of the samplers: the MAP and its Laplace
        covariance, sigma last (its std on the diagonal)."""
        theta = np.append(self.theta_map, self.sigma_map)
        covariance = np.zeros((len(theta), len(theta)))
        covariance[:-1, :-1] = self.covariance
        covariance[-1, -1] = self.sigma_std**2
        return theta, covariance


def sample(
    model: BlockModel, laplace: LaplaceReport, method: str, settings: dict, rng: np.random.Generator, progress=None
) -> list[Chain]:
    """Chains of one method on the model's posterior.

    paper: the paper's Metropolis from Theta = 0, sigma = 1 mm; default: adaptive Metropolis from
    overdispersed starts drawn from the Laplace approximation (`overdispersed_starts`), proposal
    seeded by the Laplace covariance, run on until the convergence criteria hold
    (settings["convergence"]: max_rhat, min_ess; its kept part doubled at most
    settings["max_doublings"] times); emcee: walkers in a Laplace-sized ball around the MAP (one
    ensemble, its walkers split in two halves for R-hat), doubled the same way.
    """
    target = PosteriorTarget(model)
    start, covariance = laplace.start()
    if method == "paper":
        paper_start = np.append(np.zeros(len(model.names)), 1e-3)
        return run_chains(
            metropolis_paper,
            target,
            rng,
            settings["chains"],
            paper_start,
            n_samples=settings["samples"],
            burn_in=settings["burn_in"],
            half_width=settings["half_width"],
            progress=progress,
        )
    if method == "default":
        return run_chains(
            metropolis_adaptive,
            target,
            rng,
            settings["chains"],
            overdispersed_starts(start, covariance, settings["chains"], rng),
            enough=_converged_chains(target.names, settings.get("convergence")),
            max_doublings=settings.get("max_doublings", 0),
            covariance=covariance,
            n_samples=settings["samples"],
            burn_in=settings["burn_in"],
            progress=progress,
        )
    if method == "emcee":
        return [
            run_emcee(
                target,
                rng,
                start,
                np.sqrt(np.diag(covariance)),
                n_walkers=settings["walkers"],
                n_steps=settings["steps"],
                burn_in=settings["burn_in"],
                enough=converged_ensemble(target.names, settings.get("convergence")),
                max_doublings=settings.get("max_doublings", 0),
            )
        ]
    raise ValueError(f"unknown sampling method {method!r}; use one of {METHODS}")


OVERDISPERSION = 3.0  # the default sampler's chains start this many Laplace std from the MAP


def overdispersed_starts(start, covariance, n_chains: int, rng: np.random.Generator) -> np.ndarray:
    """(n_chains, P) starts start + OVERDISPERSION L z, L L^T = covariance (the Laplace
    approximation's), z ~ N(0, I): three std out along the posterior's own shape. Drawn
    independently per coordinate, three std out in a direction the parameters' correlation makes
    narrow would be hundreds of std from the posterior, a start the adaptive burn-in spends its
    steps coming back from. sigma (last) stays positive."""
    start = np.asarray(start, dtype=float)
    covariance = np.asarray(covariance, dtype=float)
    try:
        factor = np.linalg.cholesky(covariance)
    except np.linalg.LinAlgError:  # not positive definite by round-off: the marginal std alone
        factor = np.diag(np.sqrt(np.clip(np.diag(covariance), 0.0, None)))
    starts = start + OVERDISPERSION * rng.standard_normal((n_chains, len(start))) @ factor.T
    starts[:, -1] = np.abs(starts[:, -1])
    return starts


def _converged_chains(names, criteria: Mapping | None):
    """The test that chains meet the cross-check's criteria (max_rhat, min_ess), judged as
    `sampler_diagnostics` judges them; None without criteria."""
    if criteria is None:
        return None

    def enough(chains) -> bool:
        report = diagnostics.chain_report(chains, list(names))
        return converged(_extremes(report), criteria["max_rhat"], criteria["min_ess"])

    return enough


def _extremes(report: pd.DataFrame) -> dict:
    """{'max_rhat', 'min_ess'} of a `diagnostics.chain_report` (min_ess: the smaller of the bulk
    and the tail ESS), NaN when any parameter's is NaN (a parameter whose chains never move has
    no R-hat: that is not convergence, and a max that skipped it would say it is)."""
    rhat = report["rhat"].to_numpy(dtype=float)
    ess = np.minimum(report["ess_bulk"].to_numpy(dtype=float), report["ess_tail"].to_numpy(dtype=float))
    return {
        "max_rhat": float(np.max(rhat)) if rhat.size else math.nan,
        "min_ess": float(np.min(ess)) if ess.size else math.nan,
    }


def converged_ensemble(names, criteria: Mapping | None):
    """The test that an ensemble's kept paths (n_steps, n_walkers, P) meet the cross-check's
    criteria (max_rhat, min_ess), judged as `sampler_diagnostics` judges it (the walkers' two
    halves as two chains); None without criteria."""
    if criteria is None:
        return None

    def enough(paths: np.ndarray) -> bool:
        half = paths.shape[1] // 2
        report = diagnostics.chain_report([paths[:, :half], paths[:, half:]], list(names))
        return converged(_extremes(report), criteria["max_rhat"], criteria["min_ess"])

    return enough


def samples_frame(chains: list[Chain]) -> pd.DataFrame:
    """Posterior samples (SI), one row per kept state: parameters, log_prob, chain, walker, step."""
    frames = []
    for number, chain in enumerate(chains):
        steps = np.repeat(np.arange(chain.n_steps), chain.n_walkers)
        walkers = np.tile(np.arange(chain.n_walkers), chain.n_steps)
        frame = pd.DataFrame(chain.samples, columns=list(chain.names))
        frame["log_prob"] = chain.log_prob
        frame["chain"] = np.int64(number)
        frame["walker"] = walkers.astype(np.int64)
        frame["step"] = steps.astype(np.int64)
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def trace_frame(chains: list[Chain], every: int = 100) -> pd.DataFrame:
    """The whole run of each chain, every `every`-th step, burn-in included where the sampler
    kept it (the paper's); step counts from the first step. For an ensemble, walker 0."""
    frames = []
    for number, chain in enumerate(chains):
        burn_in = chain.settings.get("burn_in", 0)
        kept = chain.per_walker()[::every, 0]
        parts, steps = [kept], [burn_in + every * np.arange(len(kept))]
        if "burn_in_trace" in chain.settings:
            early = chain.settings["burn_in_trace"]
            parts.insert(0, early)
            steps.insert(0, chain.settings["trace_every"] * np.arange(len(early)))
        frame = pd.DataFrame(np.concatenate(parts), columns=list(chain.names))
        frame["step"] = np.concatenate(steps).astype(np.int64)
        frame["chain"] = np.int64(number)
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def chains_of(frame: pd.DataFrame, names) -> list[np.ndarray]:
    """Samples back into per-chain (n, W, P) arrays, the layout the diagnostics take."""
    out = []
    for _, part in frame.groupby("chain", sort=True):
        walkers = int(part["walker"].max()) + 1
        values = part.sort_values(["step", "walker"])[list(names)].to_numpy()
        out.append(values.reshape(-1, walkers, len(names)))
    if len(out) == 1 and out[0].shape[1] >= 4:  # one ensemble: its two halves of walkers as two chains
        half = out[0].shape[1] // 2
        out = [out[0][:, :half], out[0][:, half:]]
    return out


def sampler_diagnostics(chains: list[Chain], seconds: float) -> dict:
    """JSON-ready: per-parameter report (tau, ESS, R-hat, MCSE), acceptance, ESS per second, and
    how often the run doubled to meet its criteria. min_ess and max_rhat are NaN (null in the
    file) when a parameter's is: `converged` then says no, as it must for a chain that never
    moved."""
    frame = samples_frame(chains)
    names = list(chains[0].names)
    report = diagnostics.chain_report(chains_of(frame, names), names)
    extremes = _extremes(report)
    return {
        "method": chains[0].method,
        "chains": len(chains),
        "walkers": chains[0].n_walkers,
        "kept_per_chain": chains[0].n_steps,
        "doublings": int(chains[0].settings.get("doublings", 0)),
        "acceptance_rate": [c.acceptance_rate for c in chains],
        "seconds": seconds,
        "min_ess": extremes["min_ess"],
        "min_ess_per_second": extremes["min_ess"] / seconds if seconds > 0 else None,
        "max_rhat": extremes["max_rhat"],
        "rhat_undefined": [n for n, r in report["rhat"].items() if not np.isfinite(r)],
        "parameters": report.reset_index().to_dict(orient="records"),
    }


def converged(diagnostics_report: Mapping | None, max_rhat: float, min_ess: float) -> bool:
    """A sampler's own verdict: every R-hat below max_rhat and every ESS above min_ess. A value
    that is missing, None (NaN as a JSON file holds it) or NaN is not a pass: no diagnostics,
    no verdict of convergence."""
    report = diagnostics_report or {}
    rhat, ess = _number(report.get("max_rhat")), _number(report.get("min_ess"))
    return rhat <= max_rhat and ess >= min_ess  # False for NaN


def _number(value) -> float:
    """value as a float, NaN for None or anything that is not a number."""
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


def cross_check(
    samples: dict[str, pd.DataFrame],
    sampler_reports: Mapping[str, Mapping | None],
    laplace: LaplaceReport,
    tolerance: float,
    max_rhat: float,
    min_ess: float,
    floor: float,
) -> pd.DataFrame:
    """Every method's posterior mean and std per parameter and its disagreement with the default
    sampler in units of combined Monte Carlo error (`diagnostics.cross_check`), as a flat table:
    parameter, then mean_<method>, std_<method>, z_<method>, checked_<method>, disagrees_<method>
    (SI), and `disagreement`: the methods that disagree on the parameter ("" where none does).

    The agreement is checked among the methods that converged by their own diagnostics and the
    least-squares/Laplace solution: disagrees_<method> is True where such a method is more than
    `tolerance` errors from the default sampler (or its z is NaN). A disagreement is marked, not
    raised: the campaign's results and report are made anyway, and the certificate says that the
    fit is not confirmed by a second sampler (`disagreeing`). A method that did not converge (the
    paper's sampler usually: its chain does not travel far enough in 2e5 small steps) is shown
    with its z and checked_<method> False, since its means carry a bias its MCSE does not
    measure. `floor` (fit/cross_check/floor, the one floor of every cross-check): the combined
    error is at least this fraction of the posterior std, because an ESS from chains of a few
    dozen autocorrelation times is itself uncertain; a difference of 0.1 std in a posterior mean is
    far below what the posterior itself leaves uncertain. A method without diagnostics
    counts as not converged.
    """
    names = list(laplace.names) + [SIGMA]
    results = {}
    for method in ("default",) + tuple(m for m in samples if m != "default"):
        results[method] = diagnostics.moments(chains_of(samples[method], names))
    lap_mean = np.append(laplace.theta_map, laplace.sigma_mean)
    lap_std = np.append(laplace.std, laplace.sigma_std)
    results["laplace"] = (lap_mean, lap_std, np.zeros_like(lap_mean))
    table = diagnostics.cross_check(results, names, tolerance=None, reference="default", floor=floor)
    enforced = ["default", "laplace"] + [
        m for m in samples if m != "default" and converged(sampler_reports.get(m), max_rhat, min_ess)
    ]
    offenders = diagnostics.disagreements(table.loc[:, [c for c in table.columns if c[1] in enforced]], tolerance)
    flat = pd.DataFrame(index=table.index)
    for method in results:
        for quantity in ("mean", "std", "z"):
            flat[f"{quantity}_{method}"] = table[(quantity, method)]
        flat[f"checked_{method}"] = method in enforced
        flat[f"disagrees_{method}"] = [(name, method) in {(o[0], o[1]) for o in offenders} for name in flat.index]
    flat["disagreement"] = [", ".join(o[1] for o in offenders if o[0] == name) for name in flat.index]
    if offenders:
        log.warning(
            "the samplers disagree beyond %g combined Monte Carlo errors (the fit is not confirmed by a second "
            "sampler): %s",
            tolerance,
            "; ".join(f"{name}: {method} vs {reference} (z = {z:+.2f})" for name, method, reference, z in offenders),
        )
    out = flat.reset_index()
    out.attrs["disagreements"] = offenders
    return out


def disagreeing(table: pd.DataFrame) -> dict[str, list[str]]:
    """{parameter: [methods]} on which a `cross_check` table (as made, or read back from
    cross_check.csv) records a disagreement; {} when every checked method agrees."""
    out = {}
    for name, methods in zip(table["parameter"], table["disagreement"]):
        if isinstance(methods, str) and methods.strip():
            out[str(name)] = [m.strip() for m in methods.split(",") if m.strip()]
    return out


def moments(samples: pd.DataFrame) -> pd.DataFrame:
    """Per column of posterior samples (draws, parameters): mean, std (ddof 1) and the 95 %
    interval q2.5, q97.5, in the samples' units; one row per parameter. The one summary of
    samples that the paper's fit and the loop closure's refit share."""
    return pd.DataFrame(
        {
            "mean": samples.mean(),
            "std": samples.std(ddof=1),
            "q2.5": samples.quantile(0.025),
            "q97.5": samples.quantile(0.975),
        }
    )


def mode_summary(laplace: LaplaceReport) -> pd.DataFrame:
    """`posterior_summary` of the model at its Laplace mode alone (no samples: std and interval
    undefined): what a calibration needs (mean, status) where no sampler ran."""
    mode = pd.DataFrame([{**dict(zip(laplace.names, laplace.theta_map)), SIGMA: laplace.sigma_map}])
    return posterior_summary(mode, laplace)


def posterior_summary(frame: pd.DataFrame, laplace: LaplaceReport) -> pd.DataFrame:
    """Per parameter: MLE (the posterior mean, as in the paper), std and 95 % interval in SI and
    in display units (mm, deg), and its status; held parameters appear with status 'held'."""
    summary = moments(frame[list(laplace.names) + [SIGMA]])
    summary["status"] = "estimated"
    reasons = laplace.held_reasons or {}
    for name, value in laplace.held.items():
        summary.loc[name] = [value, np.nan, np.nan, np.nan, f"held: {reasons.get(name, 'not identifiable')}"]
    summary = summary.loc[list(laplace.parameters) + [SIGMA]]
    scale = np.array([display_scale(n) for n in summary.index])
    for column in ("mean", "std", "q2.5", "q97.5"):
        summary[f"{column}_display"] = summary[column].astype(float) / scale
    summary["display_unit"] = [display_unit(n) for n in summary.index]
    summary.index.name = "parameter"
    return summary


def remastering(summary: pd.DataFrame, joint_names, campaign: str, sensor: str) -> dict:
    """The new zero-offset corrections (deg) with their uncertainty, ready to type into a controller:
    new zero = old zero + correction. Held joints get no correction and say why. `summary` as
    `posterior_summary` gives it, indexed by parameter or with a parameter column."""
    if "parameter" in summary.columns:
        summary = summary.set_index("parameter")
    joints = []
    for j, joint in enumerate(joint_names):
        row = summary.loc[f"zero_offsets.q{j + 1}"]
        held = row["status"] != "estimated"
        joints.append(
            {
                "joint": joint,
                "correction_deg": float(row["mean_display"]),
                "std_deg": None if held else float(row["std_display"]),
                "interval_95_deg": None if held else [float(row["q2.5_display"]), float(row["q97.5_display"])],
                "status": row["status"],
            }
        )
    return {
        "campaign": campaign,
        "sensor": sensor,
        "convention": "controller zero += correction (deg)",
        "joints": joints,
    }


# --------------------------------------------------------------------------- workflow stages


def registration_stage(campaign: Campaign, sensor: str) -> Registration:
    """The initial registration of one sensor (`report()` is what registration.json holds). A set of
    points no frame can be fitted to (in the robot's model or as measured: on one line) is an
    InputError naming the campaign's sensor file and its optimization rows."""
    data = campaign.sensors[sensor]
    try:
        return register(campaign.chain, data)
    except InputError as error:
        raise InputError(
            f"the optimization set cannot register the sensor: {error.key or 'points'}: {error.reason}",
            file=f"{campaign.name}/{sensor}.parquet",
            rows=data.measured_rows("optimization"),
        ) from None


def _model(campaign: Campaign, sensor: str, registration: Registration, exclude=(), orientation_weight=None):
    return build_model(
        campaign.chain,
        campaign.sensors[sensor],
        registration.t_nr,
        exclude=exclude,
        orientation_weight=orientation_weight,
    )


def laplace_stage(campaign: Campaign, sensor: str, registration: Registration, outlier_alpha: float) -> dict:
    """Outlier screening, identifiability analysis and least-squares/Laplace fit of one sensor,
    JSON-ready. The screen is provisional (`flag_outliers`): its rows are left out of the paper
    model's fit and listed; the loop closure starts without them and screens every row again."""
    model, _, _ = _model(campaign, sensor, registration)
    outliers = flag_outliers(model, outlier_alpha)
    if len(outliers):
        log.warning(
            "%s: %d points flagged provisionally as gross errors (zero-offset model) and left out of its fit: rows %s",
            sensor,
            len(outliers),
            outliers.tolist(),
        )
    model, analysis, excluded = _model(campaign, sensor, registration, exclude=outliers)
    for statement in analysis.statements():
        log.info("%s: %s", sensor, statement)
    stated = model.data.orientation_weight
    model = balanced_orientation(model)
    result = laplace_fit(model)
    report = laplace_report(result, analysis, excluded, outliers, model)
    if model.has_orientation:
        points, points_analysis, _ = build_model(
            campaign.chain, campaign.sensors[sensor], registration.t_nr, exclude=outliers, orientation=False
        )
        report["orientation"] = orientation_added(result, analysis, laplace_fit(points), points_analysis, model)
        report["orientation"]["stated_noise_ratio_m_per_rad"] = stated
    return report


def sampling_stage(
    campaign: Campaign,
    sensor: str,
    registration: Registration,
    laplace: LaplaceReport,
    method: str,
    settings: dict,
    rng: np.random.Generator,
    progress=None,
) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """(posterior samples, thinned trace of the whole run, sampler diagnostics) of one method for one sensor."""
    model, _, _ = _model(
        campaign, sensor, registration, exclude=laplace.outlier_rows, orientation_weight=laplace.orientation_weight
    )
    laplace.check_names(model.names)
    started = time.perf_counter()
    chains = sample(model, laplace, method, settings, rng, progress)
    seconds = time.perf_counter() - started
    return samples_frame(chains), trace_frame(chains), sampler_diagnostics(chains, seconds)


def prepare_stage(campaign: Campaign, sensor: str, outlier_alpha: float) -> tuple[dict, dict]:
    """(registration.json, laplace.json) contents of one sensor: the initial registration, then the
    outlier screen, identifiability analysis and Laplace fit from it. The fit starts from the
    registration as its file holds it (`Registration.of(report)`), so the two files always agree."""
    registration = registration_stage(campaign, sensor).report()
    return registration, laplace_stage(campaign, sensor, Registration.of(registration), outlier_alpha)
