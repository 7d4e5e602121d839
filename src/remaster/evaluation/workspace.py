"""Where a calibration holds: the loop-closed model's theoretical accuracy and the workspace-wide
error of the paper's and the loop-closed model: what a calibration claims beyond the measured
poses.

Configurations, three sets:

- 'optimization': the optimization set's (every row, the marker seen or not: the joint readings are
  valid either way; beyond as many rows as there are random configurations, that many evenly spaced
  rows, so that the posterior draws' points (draws x rows x 3) stay within a job's memory on a
  campaign of any size);
- 'domain': random configurations near the measured ones (within the data's own spacing, in how
  far the marker moves), a held joint at its value (`domain.MeasuredDomain`, `robot.nearness`);
- 'random': the robot's one fixed set of random configurations across the joint limits
  (`prediction.robot_configurations`), where the
  parameters the data did not determine spread by their priors.

Two kinds of claim:

- **Robot frame, the paper's propagation** (rows "Loop-closed" of the paper's theoretical tables):
  the distance between the loop-closed model's TCP at its posterior mean and the TCP of each of its
  posterior draws (whole MCMC rows: every parameter of its effects, and sigma), with each draw's
  N(0, sigma^2 I3) added ("with noise") or not ("without noise", the row of the zero-offsets-only
  table). Held zero-offsets stay held, as in the paper's rows, so these numbers hold up to a
  rotation about base Z (joint 1 of the iiwa: no registration-free data fixes it); so do, by the
  same convention, the extension parameters the data cannot see (a base height absorbed by the
  registration, a compliance of a joint that never carries a torque), which the workspace-wide
  claim below keeps under their priors. The variant
  "robot frame, held joints at the controller's marks" draws every held zero-offset from
  N(held value, tolerance^2) (`priors`: held_zero_offset_deg) and is the robot-frame claim.
- **Registration fitted** (the workspace-wide claim): the error a sensor registered over those
  configurations would see. For each posterior draw d of the loop-closed model, the model under
  test is moved onto the draw's points by least squares (`metrics.registered_distances`) and
  |T_d p_model(q) - (p_d(q) + n_d)| is its error at q ("with noise"; "without noise" leaves n_d
  out). Where the loop is not closed, p_d carries the model error it declares
  (`LoopReport.declared_model_error`), drawn as a field over the joints with the kernel of its residual
  (`LoopReport.declared_field`: what a model lacks is correlated from one configuration to the next, and
  a p95 over configurations of independent draws has almost no spread), or per axis and configuration
  where the loop fitted no kernel. Held zero-offsets are drawn at the
  controller marks' tolerance here too: the registration removes joint 1's, but one held only
  because these data never turned it (the last joint when the tool keeps one orientation) moves
  the marker at other poses. Not the last joint's where the loop fits a marker offset: its turn
  moves the marker as an offset does at every configuration, so the fitted offset holds it
  (`parameter_blocks.carried_by_marker_offset`). The loop-closed posterior is the reference
  because it is the model with the most evidence the loop found: for the loop-closed model itself
  this is its own posterior spread; for the paper's model (its posterior means) it adds what the
  loop closure found the paper's model lacks. What no candidate effect explains is in the
  loop-closed model's sigma as noise or, when the loop added its residual GP, in the GP: its mean
  corrects the loop-closed model and its variance (its prior's far from the measured
  configurations) is drawn at every configuration, with the GP's noise as the noise.

Where the claims hold is the measured domain's verdict (`domain.MeasuredDomain.holds`): "across the
joint limits" only when every joint's interval covers `domain.FULL_RANGE_FRACTION` of its range and
the tool axes spread `domain.MIN_TOOL_SPREAD_DEG`; otherwise "near the measured configurations", and the
claim across the limits is shown apart, as the claim with the priors of what the data did not reach.
(Comparing the model's own claim at random configurations with its own claim at the measured ones
cannot see what the model cannot represent: that ratio is kept as information only.) The report
says what the next campaign must add: the joints whose measured range covers less than
`FULL_RANGE_FRACTION` of their limits, more tool orientations when every measured flange axis lies
within `MIN_TOOL_SPREAD_DEG` of one direction, and the parameters the data barely moved from their
prior but random configurations would show (`extensions.identifiable_extension` there); those no
external measurement sees anywhere (a base height absorbed by the registration) are listed apart.

SI inside (m, rad); the returned tables are in mm.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pandas as pd

from ..calibration.prediction import Calibration, Propagation, loop_calibration, paper_calibration, robot_configurations
from ..campaigns.campaign import SensorData
from ..errors import InputError
from ..evaluation.domain import ACROSS, FULL_RANGE_FRACTION, INSIDE, MIN_TOOL_SPREAD_DEG, MeasuredDomain
from ..inference import metrics
from ..inference.bounds import bound_on_percentile_over_configurations
from ..inference.extensions import identifiable_extension
from ..inference.gp import loop_candidate
from ..inference.gp.kernels import Hyperparameters
from ..inference.gp.residual import ResidualGP, evenly_spaced, model_error_draws
from ..inference.laplace_report import LaplaceReport
from ..inference.model import SIGMA
from ..inference.parameter_blocks import carried_by_marker_offset
from ..loop.refit import PRIOR_DOMINATED
from ..loop.result import LoopReport, LoopResults
from ..robot.kinematics import KinematicChain
from ..units import DEG, MM, shown

LOOP_METHOD = "Loop-closed"
THEORETICAL_TABLES = {  # paper table: (configurations, with noise)
    "theoretical_accuracy_optimization_configs": ("optimization", True),
    "theoretical_accuracy_random_configs": ("random", True),
    "theoretical_accuracy_zero_offsets_only": ("random", False),
}
CONFIGURATIONS = {
    "optimization": "measured (optimization set)",
    "domain": "random inside the measured joint ranges",
    "random": "random across the joint limits (priors where the data did not reach)",
}
FRAMES = {"registered": "registration fitted", "robot": "robot frame, held joints at the controller's marks"}
CLAIM_COLUMNS = [
    "model",
    "configurations",
    "frame",
    "noise",
    "mean_mm",
    "q2.5_mm",
    "q97.5_mm",
    "p95_mm",
    "p95_bound_mm",
    "p95_bound_data_mm",
    "count",
]
# A claim whose bound the data determine less than half of (the rest is what the priors of the
# parameters the data barely moved, and the controller marks' tolerance of a held joint, supply:
# more than three quarters of its square) is the priors' statement, not a measurement: not determined
PRIORS_DECIDE = 0.5
HELD_NOTE = (
    "held zero-offsets ({held}) are held in the draws, as in the paper's rows: these robot-frame numbers "
    "hold up to a rotation about base Z that only a registration fixes"
)


@dataclass(frozen=True, eq=False)
class WorkspaceAccuracy:
    """theoretical: rows (table, method, mean_mm, q2.5_mm, q97.5_mm, count) for the paper's
    theoretical tables; claims: `CLAIM_COLUMNS`, one row per model, configurations, frame and
    noise; report: JSON-ready (warnings, suggestions, notes)."""

    theoretical: pd.DataFrame
    claims: pd.DataFrame
    report: dict


def _claim_row(distances_m, **labels) -> dict:
    """A claim's row of errors (draws, configurations) m, in mm: the pooled distribution (mean,
    2.5 %, 97.5 % and 95 % quantiles: the error at a random configuration of a random draw) and
    `p95_bound_mm`, the 95 % bound on one arm's own 95 % quantile over the configurations
    (`bounds.bound_on_percentile_over_configurations`)."""
    summary = metrics.in_mm(metrics.error_summary(distances_m, (*metrics.INTERVAL, "p95")))
    return {**labels, **summary, "p95_bound_mm": bound_on_percentile_over_configurations(distances_m) / MM}


def priors_decide(bound_mm: float, data_part_mm: float) -> bool:
    """Whether the priors, not the data, decide a claim's bound: its part the data determine (what the
    priors decide held at its mean, held joints at their marks: `_Posterior.data_draws`) is below
    PRIORS_DECIDE of it. False when the split is unknown (NaN)."""
    return bool(np.isfinite(bound_mm) and np.isfinite(data_part_mm) and data_part_mm < PRIORS_DECIDE * bound_mm)


def _with_noise(points, sigma, rng: np.random.Generator):
    """points (m, n, 3) with each draw's N(0, sigma_d^2 I3) added."""
    return points + np.asarray(sigma)[:, None, None] * rng.standard_normal(points.shape)


def _gp_draws(gp: ResidualGP | None, q, count: int, rng: np.random.Generator):
    """The residual GP's mean (n, 3) m at readings q (n, N) and `count` draws (count, n, 3) of it,
    jointly across the configurations (`ResidualGP.draws`: each draw's p95 over them is one of a
    function the robot could have); zeros without a GP (and no random draw)."""
    if gp is None:
        return 0.0, 0.0
    return gp.mean(q), gp.draws(q, count, rng)


def _held_draws(draws: list[dict], held: Mapping[str, float], tolerance: float, rng: np.random.Generator):
    """The draws with every held zero-offset drawn from N(held value, tolerance^2)."""
    names = sorted(held)
    shifts = tolerance * rng.standard_normal((len(draws), len(names)))
    return [{**d, **{n: float(held[n]) + s for n, s in zip(names, row)}} for d, row in zip(draws, shifts)]


def _suggestions(domain: MeasuredDomain, dominated: list[str]) -> list[str]:
    """What the next campaign must add, from the measured domain and the prior-dominated parameters:
    the joints short of `FULL_RANGE_FRACTION` of their range, tool orientations when the measured
    axes spread less than `MIN_TOOL_SPREAD_DEG`, poses that move the prior-dominated parameters."""
    out = [
        f"joint {j + 1} over more of its range (measured: "
        + (f"held at {low / DEG:.0f} deg" if held else f"{100 * f:.0f} % of it")
        + ")"
        for j, (f, held, low) in enumerate(zip(domain.range_fraction, domain.held, domain.lower))
        if f < FULL_RANGE_FRACTION
    ]
    if domain.tool_axis_spread_deg < MIN_TOOL_SPREAD_DEG:
        out.append(
            f"tool orientations (every measured flange axis lies within "
            f"{domain.tool_axis_spread_deg:.0f} deg of one direction)"
        )
    if dominated:
        out.append(
            "poses that move "
            + ", ".join(dominated)
            + f" (the data barely moved them from their prior: posterior std / prior std > {PRIOR_DOMINATED:g})"
        )
    return out


def fit_domain(chain: KinematicChain, sensor: SensorData, outlier_rows=()) -> MeasuredDomain:
    """The measured domain of the readings the fit used: the optimization rows whose marker was seen,
    less the rows flagged as gross errors (every optimization row when that leaves none)."""
    return MeasuredDomain.of(chain, sensor.fit_readings(outlier_rows), sensor.marker)


@dataclass(frozen=True, eq=False)
class _Posterior:
    """The posterior as `workspace_accuracy` propagates it: the loop-closed and the paper's
    calibrations; the loop's draws ({parameter: value} each, every parameter) with their noise std
    sigma (m); the held zero-offsets {name: rad}, drawn at the marks' tolerance (rad); what the data
    cannot see {name: value}, held in the paper's tables; carried: the held zero-offsets the loop's
    free marker offset carries (`parameter_blocks.carried_by_marker_offset`), not drawn; the
    residual GP, None without one; the
    model error per axis (m) the loop declares (`LoopReport.declared_model_error`, zero where it
    closed) and its field (`LoopReport.declared_field`: drawn as a field over the joints in the
    claims; None: independently per axis and configuration); each estimated parameter's prior std
    (SI), for `data_draws`."""

    loop: Calibration
    paper: Calibration
    draws: list[dict]
    sigma: np.ndarray
    held: dict[str, float]
    tolerance: float
    unseen: dict[str, float]
    gp: ResidualGP | None
    declared: float = 0.0
    declared_field: Hyperparameters | None = None
    prior_std: Mapping[str, float] = field(default_factory=dict)
    carried: frozenset[str] = frozenset()

    @property
    def drawn(self) -> dict[str, float]:
        """The held zero-offsets drawn at the marks' tolerance: not one the marker offset carries."""
        return {n: v for n, v in self.held.items() if n not in self.carried}

    @cached_property
    def data_draws(self) -> list[dict]:
        """The draws with what the priors decide taken out, held zero-offsets at their marks (their
        tolerance not drawn). In units of each parameter's prior std, the directions in which the
        posterior's spread is more than PRIOR_DOMINATED of the prior's (eigenvectors of the draws'
        covariance there: combinations of parameters the data left to the priors) are what the
        priors decide; every parameter (the registration included) is conditioned on them at their
        mean, by regression on them over the draws (the Gaussian conditional), so that what the
        other parameters trade with those directions goes with them."""
        names = [n for n in self.prior_std if n in self.draws[0]] if self.draws else []
        if not names:
            return self.draws
        scale = np.array([self.prior_std[n] for n in names])
        standard = np.array([[d[n] for n in names] for d in self.draws]) / scale
        standard -= standard.mean(axis=0)
        spread, directions = np.linalg.eigh(np.atleast_2d(np.cov(standard, rowvar=False)))
        decided = standard @ directions[:, spread > PRIOR_DOMINATED**2]  # (K, r) the priors' coordinates
        if decided.shape[1] == 0:
            return self.draws
        every = [n for n, v in self.draws[0].items() if isinstance(v, float)]
        values = np.array([[d[n] for n in every] for d in self.draws])
        slope = np.linalg.lstsq(decided, values - values.mean(axis=0), rcond=None)[0]
        data = values - decided @ slope
        return [{**d, **dict(zip(every, row))} for d, row in zip(self.draws, data.tolist())]


def _posterior(
    chain: KinematicChain, paper_summary: pd.DataFrame, laplace: LaplaceReport, loop: LoopResults, rng, count: int
) -> _Posterior:
    """`count` draws of the loop closure's MCMC samples (rng), and what goes with them (`_Posterior`)."""
    samples = loop.samples
    if samples is None or samples.empty or SIGMA not in samples.columns:
        raise InputError(
            "the loop closure wrote no MCMC samples (with sigma): its posterior cannot be propagated",
            file=loop.label,
            key="samples",
        )
    calibration = loop_calibration(loop.report, samples, loop.label)
    rows = rng.choice(len(samples), count, replace=len(samples) < count)
    gp = loop_candidate.from_results(loop.gp_rows, loop.report.residual_gp)
    held = laplace.held_zero_offsets
    return _Posterior(
        loop=calibration,
        paper=paper_calibration(paper_summary, None, loop.label),
        draws=[{**calibration.values, **d} for d in calibration.draws.iloc[rows].to_dict(orient="records")],
        # with a residual GP the noise is its white part
        sigma=samples[SIGMA].to_numpy(float)[rows] if gp is None else np.full(count, gp.hyper.noise_std),
        held=held,
        tolerance=loop.report.held_zero_offset_std,
        # what the data cannot see is held in the paper's robot-frame rows (joint 1 there): the same here
        unseen={n: calibration.values[n] for n in loop.report.unseen_by_data if n in calibration.values},
        gp=gp,
        declared=loop.report.declared_model_error("loop") or 0.0,
        declared_field=loop.report.declared_field(),
        prior_std=_prior_std(loop.report.parameters),
        carried=carried_by_marker_offset(chain.n_joints, held, calibration.draws.columns),
    )


def _prior_std(parameters: pd.DataFrame) -> dict[str, float]:
    """{parameter: prior std (SI)} of the estimated parameters with a prior (the loop's parameter
    table: std / posterior_to_prior_std)."""
    table = parameters[(parameters["status"] == "estimated") & (parameters["posterior_to_prior_std"] > 0)]
    return {
        str(n): float(s) / float(r)
        for n, s, r in zip(table["parameter"], table["std"], table["posterior_to_prior_std"])
        if np.isfinite(float(s) / float(r))
    }


def _claims_at(chain: KinematicChain, marker, where: str, q, posterior: _Posterior, rng) -> tuple[list, list]:
    """(theoretical rows, claim rows) at one set of configurations q (n, N): the paper's tables made
    there (`THEORETICAL_TABLES`) and each model's claim, registered with and without noise and in the
    robot frame; rng draws the GP, the held zero-offsets and the noise."""
    count = len(posterior.draws)
    predictor = posterior.loop.predictor(chain, q, marker)
    correction, corrections = _gp_draws(posterior.gp, q, count, rng)
    loop_mean = predictor.points(posterior.loop.values) + correction
    # the claims: every parameter under its posterior, held zero-offsets at the marks' tolerance
    # (a registration removes joint 1's; one held only because the tool never turned stays)
    points_parametric = predictor.points_of_draws(
        _held_draws(posterior.draws, posterior.drawn, posterior.tolerance, rng)
    )
    points = points_parametric + corrections
    if posterior.declared > 0:  # a loop not closed claims what it measured beyond the noise
        points = points + model_error_draws(posterior.declared, posterior.declared_field, q, count, rng)
    noisy = _with_noise(points, posterior.sigma, rng)
    # the part the data determine: the same draws with what the priors decide held (same noise)
    data_points = predictor.points_of_draws(posterior.data_draws) + (points - points_parametric)
    data_noisy = data_points + (noisy - points)
    paper_points = posterior.paper.predictor(chain, q, marker).points(posterior.paper.values)
    tables = {table: noise for table, (at, noise) in THEORETICAL_TABLES.items() if at == where}
    if tables:  # the paper's tables' convention: what the data cannot see, held
        seen = predictor.points_of_draws([{**d, **posterior.unseen} for d in posterior.draws]) + corrections
        seen_noisy = _with_noise(seen, posterior.sigma, rng)
    theoretical, claims = [], []
    for table, noise in tables.items():
        distances = np.linalg.norm((seen_noisy if noise else seen) - loop_mean, axis=-1)
        theoretical.append(
            {
                "table": table,
                "method": LOOP_METHOD,
                **metrics.in_mm(metrics.error_summary(distances)),
            }
        )
    for model, mean in (("paper", paper_points), ("loop", loop_mean)):
        for noise, reference, data in (("with noise", noisy, data_noisy), ("without noise", points, data_points)):
            row = _claim_row(
                metrics.registered_distances(mean, reference),
                model=model,
                configurations=where,
                frame="registered",
                noise=noise,
            )
            data_bound = bound_on_percentile_over_configurations(metrics.registered_distances(mean, data))
            claims.append({**row, "p95_bound_data_mm": data_bound / MM})
        claims.append(
            _claim_row(
                np.linalg.norm(noisy - mean, axis=-1),
                model=model,
                configurations=where,
                frame="robot",
                noise="with noise",
            )
        )
    return theoretical, claims


def workspace_accuracy(
    chain: KinematicChain,
    sensor: SensorData,
    robot: str,
    paper_summary: pd.DataFrame,
    laplace: LaplaceReport,
    loop: LoopResults,
    rng: np.random.Generator,
    propagation: Propagation,
) -> WorkspaceAccuracy:
    """The loop-closed model's theoretical accuracy and both models' workspace-wide claims (see the
    module docstring). paper_summary: the fit's summary.csv; laplace: its Laplace report (held
    parameters); loop: the loop closure's report, MCMC samples (SI) and residual-GP training rows
    (empty or None when it added none); robot: the robot's identity (its random configurations come
    from the propagation's seed and it); rng draws the posterior rows, the noise and the held
    zero-offsets. With a residual GP the loop-closed model's mean includes its correction, each draw
    a draw of it jointly across the configurations (`ResidualGP.draws`),
    and the noise is the GP's white part: far from the data its variance, back to its prior, is
    what the claim carries."""
    posterior = _posterior(chain, paper_summary, laplace, loop, rng, propagation.draws)
    n_random, seed = propagation.random_configurations, propagation.seed
    measured = sensor.q("optimization")
    used = evenly_spaced(len(measured), n_random)
    domain = fit_domain(chain, sensor, laplace.outlier_rows)
    q_sets = {  # the domain's last: the other sets' draws come from rng as they did before it
        "optimization": measured[used],
        "random": robot_configurations(chain, robot, n_random, seed),
        "domain": domain.configurations(robot, n_random, seed),
    }
    theoretical, claims = [], []
    for where, q in q_sets.items():
        rows, claimed = _claims_at(chain, sensor.marker, where, q, posterior, rng)
        theoretical += rows
        claims += claimed
    claims = pd.DataFrame(claims, columns=CLAIM_COLUMNS)
    # what no campaign can see (absorbed by a registration, or without effect) anywhere in the joint space
    predictor = posterior.loop.predictor(chain, q_sets["random"], sensor.marker)
    nowhere = sorted(identifiable_extension(predictor.model).dropped)
    report = _report(domain, sensor, claims, posterior.loop, loop.report, posterior.held, nowhere, posterior.carried)
    report["draws"] = int(propagation.draws)
    report["random_configurations"] = int(n_random)
    report["measured_configurations"] = {
        "used": len(used),
        "of": len(measured),
        "how": "every optimization row, or that many evenly spaced rows when there are more than random configurations",
    }
    return WorkspaceAccuracy(pd.DataFrame(theoretical), claims, report)


def claim_rows(
    claims: pd.DataFrame, model: str, configurations: str, frame: str = "registered", noise: str = "with noise"
) -> pd.DataFrame:
    """The rows of `claims` (`CLAIM_COLUMNS`) for one model ('paper' | 'loop'), configurations
    ('optimization' | 'domain' | 'random'), frame and noise: one row, or none when the model was not propagated."""
    return claims[
        (claims["model"] == model)
        & (claims["configurations"] == configurations)
        & (claims["frame"] == frame)
        & (claims["noise"] == noise)
    ]


def _claim(claims: pd.DataFrame, model: str, where: str, column: str = "mean_mm") -> float:
    rows = claim_rows(claims, model, where)
    return float(rows[column].iloc[0]) if len(rows) else np.nan


def _report(
    domain: MeasuredDomain, sensor, claims, loop: Calibration, loop_report: LoopReport, held, nowhere, carried
) -> dict:
    """workspace.json without its sizes (`workspace_accuracy` adds them): where the claims hold,
    the held zero-offsets (and those the fitted marker offset carries, not drawn), what the next campaign must add and the warnings."""
    dominated = [n for n in loop_report.prior_dominated if n not in nowhere]
    suggestions = _suggestions(domain, dominated)
    where = ACROSS if domain.covers_the_limits else INSIDE
    warnings, holds = [], {}
    for model in ("paper", "loop"):
        measured = _claim(claims, model, "optimization")
        inside, limits = _claim(claims, model, "domain"), _claim(claims, model, "random")
        holds[model] = {
            "measured_mean_mm": measured,
            "domain_mean_mm": inside,
            "limits_mean_mm": limits,
            # information only: the model's claim against itself cannot see what it cannot represent
            "limits_over_measured": limits / measured if measured > 0 else np.inf,
            "holds": where,
        }
    near, near_data = (_claim(claims, "loop", "domain", c) for c in ("p95_bound_mm", "p95_bound_data_mm"))
    determined = not priors_decide(near, near_data)
    if not domain.covers_the_limits:
        warnings.append(
            f"the claims hold near the measured configurations only ({domain.short_text()})"
            + (
                f": there the loop-closed model's p95 bound is {shown(near)} mm (registration fitted, with noise)"
                if determined
                else ""
            )
            + "; across the joint limits the accuracy is not determined: the data did not reach there, and the "
            f"priors of what they did not reach would give {shown(_claim(claims, 'loop', 'random', 'p95_bound_mm'))} "
            "mm, a statement of the priors, not a bound"
        )
    if not determined:
        warnings.append(
            f"near the measured configurations the accuracy is not determined either: of the loop-closed model's p95 "
            f"bound there ({shown(near)} mm) the data determine {shown(near_data)} mm; the rest is what the priors "
            "decide: the combinations of parameters the data barely moved from their prior"
            + (f" ({', '.join(dominated)} among them)" if dominated else "")
            + ", and the held joints' marks"
        )
    if suggestions:  # one line: the joints, the tool orientations and the prior-dominated parameters
        warnings.append(f"the next campaign must add: {'; '.join(suggestions)}")
    unseeable = [n for n in loop_report.prior_dominated if n in nowhere]
    if unseeable:
        warnings.append(
            f"parameters no external measurement can see anywhere in the joint space (absorbed by the "
            f"registration or without effect), left to their prior: {', '.join(unseeable)}"
        )
    return {
        "campaign": loop_report.campaign,
        "sensor": sensor.name,
        "loop_effects": list(loop.blocks),
        "configurations": dict(CONFIGURATIONS),
        "frames": dict(FRAMES),
        "held_zero_offsets": sorted(held),
        "held_tolerance_deg": loop_report.held_zero_offset_std / DEG,
        "held_in_marker_offset": sorted(carried),
        "held_note": HELD_NOTE.format(held=", ".join(sorted(held)) or "none") if held else "",
        "reference": "each draw of the loop-closed posterior (the model with the most evidence), with its noise",
        "holds": holds,
        "domain": domain.report(),
        "coverage": {
            "joint_range_fraction": [float(f) for f in domain.range_fraction],
            "tool_axis_spread_deg": domain.tool_axis_spread_deg,
        },
        "prior_dominated": dominated,
        "near_determined": determined,
        "unseen_anywhere": list(nowhere),
        "next_campaign_should_add": suggestions,
        "warnings": warnings,
    }


# --------------------------------------------------------------------------- tables of a campaign


def workspace_table(claims: Mapping[str, pd.DataFrame], reports: Mapping[str, dict]) -> pd.DataFrame:
    """One campaign's claims, every sensor: Sensor, Model, Configurations, Frame, Noise, Mean (mm),
    2.5 % / 97.5 % / 95 % quantiles (mm), the bound on the arm's own 95 % quantile (mm) and its part
    the data determine (what the priors decide held: `priors_decide`), Count, and
    where the model holds (its report's verdict)."""
    frames = []
    for sensor, frame in claims.items():
        holds = {m: h["holds"] for m, h in reports[sensor]["holds"].items()}
        frames.append(
            pd.DataFrame(
                {
                    "Sensor": sensor,
                    "Model": frame["model"],
                    "Configurations": frame["configurations"].map(CONFIGURATIONS),
                    "Frame": frame["frame"].map(FRAMES),
                    "Noise": frame["noise"],
                    "Mean (mm)": frame["mean_mm"],
                    "2.5% (mm)": frame["q2.5_mm"],
                    "97.5% (mm)": frame["q97.5_mm"],
                    "95% (mm)": frame["p95_mm"],
                    "95% bound (mm)": frame["p95_bound_mm"],
                    "95% bound, the data's part (mm)": frame["p95_bound_data_mm"],
                    "Count": frame["count"].astype(int),
                    "Holds": frame["model"].map(holds),
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def warnings_table(reports: Mapping[str, dict]) -> pd.DataFrame:
    """Sensor, Warning: every warning of every sensor's report, 'none' for a sensor without one;
    the held-joint note last."""
    rows = []
    for sensor, report in reports.items():
        texts = list(report["warnings"]) or ["none"]
        if report.get("held_note"):
            texts.append(report["held_note"])
        rows += [{"Sensor": sensor, "Warning": text} for text in texts]
    return pd.DataFrame(rows, columns=["Sensor", "Warning"])


def with_loop_rows(paper_rows: pd.DataFrame, loop_rows: pd.DataFrame, table: str) -> pd.DataFrame:
    """One sensor's rows of a paper theoretical table with the loop-closed model's row appended
    (`WorkspaceAccuracy.theoretical`, the rows of that table)."""
    mine = loop_rows[loop_rows["table"] == table].drop(columns="table")
    return pd.concat([paper_rows, mine[paper_rows.columns]], ignore_index=True)
