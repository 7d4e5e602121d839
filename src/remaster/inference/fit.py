"""From one sensor's campaign data to a posterior ready for sampling (paper, section Optimization),
and the workflow's stages of the paper fit.

1. Initial registration T_NR: the paper's three-point method on three measured configurations
   of the optimization set chosen far apart (nominal forward kinematics gives their robot-frame
   positions); a least-squares (Kabsch) registration over every point is reported beside it.
2. Identifiability: the Jacobian of the full model at zero corrections; each undetermined
   combination gets one parameter held at the controller's value, by the same unit-free test the
   Laplace fit applies, so that the fit cannot stop on a combination the analysis passed
   (`remaster.inference.identifiability`); laplace.json states each held parameter and the
   combination it stood for (`laplace_report`).
3. The posterior over the free parameters and sigma, as a `posterior_targets.PosteriorTarget` that
   every sampler takes (`posterior_sampling`).
Points whose marker was not seen are excluded from the fit and listed.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

from .. import spatial
from ..campaigns.campaign import Campaign, SensorData
from ..errors import InputError, report_reader
from ..files import read_json
from ..robot import registration
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..spatial import transform_points
from . import gross_errors, identifiability, metrics
from .blocks import BlockModel, paper_model
from .laplace_report import LaplaceReport, laplace_fit, laplace_report, orientation_added
from .least_squares import least_squares_mode
from .model import display_scale
from .posterior_sampling import sample, sampler_diagnostics, samples_frame, trace_frame
from .posterior_targets import PosteriorTarget
from .readings import orientation_fields

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

    Provisional: a robust scale of residuals that are not noise where the model lacks an effect
    flags good rows there. Its rows are where `screened_rows` starts (the fit's own Beta/F screen,
    which restores them), and the loop closure screens every row again with its final model
    (`remaster.loop.gross`), whose rows are the gross errors listed."""
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


def screened_rows(chain: KinematicChain, data: SensorData, t_nr, outliers: Mapping[str, float]):
    """(the optimization rows of one sensor the zero-offset model leaves out as gross errors, the
    screen's record for fit/laplace.json); t_nr (4, 4) the initial registration, outliers the
    config's `outliers` (alpha, max_share). The robust screen (`flag_outliers`) gives where it starts; then the
    zero-offset model's least-squares fit of the points judges every optimization row by the rule the
    loop closure's final screen applies (`gross_errors.least_squares_screen`: Beta/F laws, isolated
    rows only), refitted without the rows it finds until they are the rows it left out. A robust
    scale of residuals that are not noise (an effect the model lacks) flags good rows, which the
    fit's own sum of squares does not."""
    alpha, max_share = float(outliers["alpha"]), float(outliers["max_share"])
    provisional = flag_outliers(build_model(chain, data, t_nr)[0], alpha)
    every, _, _ = build_model(chain, data, t_nr, orientation=False)
    poses = data.table.loc[every.data.rows, "pose"].to_numpy()
    minimum = len(every.names) + 1  # residual components a fit of the points needs beyond its parameters

    def fit_and_screen(excluded):
        points, _, _ = build_model(chain, data, t_nr, exclude=excluded, orientation=False)
        screen = gross_errors.least_squares_screen(points, laplace_fit(points), every.data, poses, alpha, max_share)
        found = screen.gross
        if 3 * (every.n_points - len(found)) <= minimum:
            found = found[:0]  # leaving them out would leave the fit undetermined (as `flag_outliers`)
        return screen, found

    record = {
        "robust_screen": [int(r) for r in provisional],
        "method": gross_errors.LEAST_SQUARES_METHOD,
        "isolated": gross_errors.ISOLATED,
        "alpha": alpha,
        "max_share": max_share,
    }
    try:
        turns = gross_errors.settle(fit_and_screen, provisional)
    except ValueError as error:  # a full-pose probe's few points alone cannot be fitted: its robust screen stands
        log.warning(
            "the zero-offset model's screen of the points alone could not be made (%s): rows %s left out",
            error,
            provisional.tolist(),
        )
        return provisional, {**record, "not_made": str(error)}
    return turns.excluded, {**record, **turns.report(), "screen": turns.fit.report()}


def laplace_stage(campaign: Campaign, sensor: str, registration: Registration, outliers: Mapping[str, float]) -> dict:
    """Gross-error screening (`screened_rows`), identifiability analysis and least-squares/Laplace
    fit of one sensor, JSON-ready; outliers: the config's `outliers` (alpha, max_share). The rows
    screened out are left out of the paper model's fit and listed; the loop closure starts without
    them and screens every row again with its final model."""
    outliers, screen = screened_rows(campaign.chain, campaign.sensors[sensor], registration.t_nr, outliers)
    if len(outliers):
        log.warning(
            "%s: %d points flagged as gross errors by the zero-offset model and left out of its fit: rows %s",
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
    report["outlier_screen"] = screen
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
    settings: Mapping[str, dict],
    rngs: Mapping[str, np.random.Generator],
    progress=None,
) -> dict[str, tuple[pd.DataFrame, pd.DataFrame, dict]]:
    """{method: (posterior samples, thinned trace of the whole run, sampler diagnostics)} of every
    method of `settings` ({method: its settings}) for one sensor, in that order. Each method draws
    from its own generator (rngs[method]), so what one gives does not depend on which others ran;
    the model is built once. progress(method, step, total, acceptance rate), if given, is called
    as each run goes."""
    model, _, _ = _model(
        campaign, sensor, registration, exclude=laplace.outlier_rows, orientation_weight=laplace.orientation_weight
    )
    laplace.check_names(model.names)
    results = {}
    for method, method_settings in settings.items():
        report = None if progress is None else functools.partial(progress, method)
        started = time.perf_counter()
        chains = sample(model, laplace, method, method_settings, rngs[method], report)
        seconds = time.perf_counter() - started
        results[method] = samples_frame(chains), trace_frame(chains), sampler_diagnostics(chains, seconds)
    return results


def prepare_stage(campaign: Campaign, sensor: str, outliers: Mapping[str, float]) -> tuple[dict, dict]:
    """(registration.json, laplace.json) contents of one sensor: the initial registration, then the
    outlier screen, identifiability analysis and Laplace fit from it. The fit starts from the
    registration as its file holds it (`Registration.of(report)`), so the two files always agree."""
    registration = registration_stage(campaign, sensor).report()
    return registration, laplace_stage(campaign, sensor, Registration.of(registration), outliers)
