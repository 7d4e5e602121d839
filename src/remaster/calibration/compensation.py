"""Put a calibration to work: where the calibrated robot puts a point at joint commands
(`predict`), and the joint commands that put it on targets (`compensate`), each with its
uncertainty from the posterior.

A `CalibratedRobot` is one campaign's sensor under one model, 'paper' or 'loop'
(`prediction.Calibration`), built from the results of `snakemake -j2` by `calibrated_robot`:

- **the point**: the sensor's marker, or a TCP (3,) m in the flange frame. The loop's marker offset
  and residual GP were measured at the marker, so they apply to the marker only;
- **frames**: 'robot' is the base frame of the nominal kinematics. The zero-offsets no sensor sees
  (a registration absorbs them: joint 1 of the iiwa) stay at the controller's marks there, and
  their tolerance (priors: held_zero_offset_deg) is drawn in every bound. 'sensor' is the
  campaign's sensor frame, p_N = (I + D)(1 + s) T*(Theta1) T_NR p_R with the fitted registration,
  sensor scale and frame distortion (D = 0 unless the loop added it): targets measured by the same sensor in the same set-up (a fixture, a workpiece).
  There the held zero-offsets a registration absorbs are part of it, whose posterior is drawn
  instead; one held because the marker never sees it (the marker on its axis) is drawn in both.
  At the marker, the last joint's held zero-offset is in the fitted marker offset where the loop
  fits one (its turn moves the marker as an offset does), and is not drawn again.

**predict**: positions (n, 3) at commands q at the posterior mean (residual GP mean added), the
nominal model's positions (in the sensor frame through the campaign's initial registration T_NR, as
an uncalibrated cell places them), and bounds from K posterior draws d (whole MCMC rows):
`bound95_mm`, the 95th percentile over d of |p_d(q) - p(q)|; `bound95_with_noise_mm`, the same with
each draw's N(0, sigma_d^2 I3) added (sigma_d: the fit's noise, or the GP's noise with a residual
GP): what the same sensor would read there. Where the loop is not closed, each draw carries the
model error it declares (`LoopReport.declared_model_error`, per axis), so the bounds hold as far
as that residual was measured. Every command is flagged: `distance_to_data_mm`, how
far the marker moves (at most, to first order) from the nearest configuration the fit measured,
and `near_data`, within the data's own spacing (`robot.nearness`). Far from the data a bound is
what the model and its priors say, not what was measured: a user who relies on it there should
measure there.

**compensate**: each target is a point t and a flange orientation R0, both from a nominal
solution q0. Nominal joint commands give it directly (t and R0: where the nominal model puts the
point and the flange). A target position gets it from the nominal model's inverse kinematics of
the point alone, started at a seed: the row's q1..qN when given, else the campaign's optimization
configuration whose nominal point is nearest. The compensated command q solves p(q) = t and
R(q) = R0 under the calibrated model, nearest to q0, by the Gauss-Newton projection

    q <- q0 + J^+ (J (q - q0) - r(q)),     r = [p(q) - t, log(R0^T R(q))],

with a forward-difference Jacobian: for a 7-joint arm it keeps the redundancy nearest q0, for 6
joints it is Newton's method. A row is not reached when the iteration does not converge (out of
reach or at a singularity: its reason says how close it came) or when the command leaves a joint's
limits (which joint, by how much). `error_mm`, `bound95_mm`, `bound95_with_noise_mm`: |p_d(q) - t|
at the posterior mean and its 95th percentile over the draws; `nominal_error_mm`: |p(q0) - t|, by
how much the nominal command misses under the calibrated model.

SI inside (m, rad); columns ending _mm or _deg are in those units.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from .. import spatial
from ..calibration.prediction import Calibration, Predictor, loop_calibration, paper_calibration
from ..calibration.tool_link import ToolSplit
from ..campaigns.campaign import Campaign
from ..errors import InputError, format_rows, require_columns
from ..inference.bounds import bound_at_points
from ..inference.gp import loop_candidate
from ..inference.gp.kernels import Hyperparameters
from ..inference.gp.residual import ResidualGP, model_error_draws
from ..inference.model import REGISTRATION, SIGMA, correction_transforms
from ..inference.parameter_blocks import DISTORTION_PARTS, MARKER_OFFSET, carried_by_marker_offset, distortion_matrix
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..robot.nearness import Nearness
from ..units import MM

MODELS = ("paper", "loop")
FRAMES = ("robot", "sensor")
SETUP = (
    tuple(f"registration.{p}" for p in REGISTRATION)
    + ("sensor_scale.s",)
    + tuple(f"sensor_distortion.{p}" for p in DISTORTION_PARTS)
)
POSITION_TOLERANCE = 1e-9  # m: a solution reproduces its target to this
ORIENTATION_TOLERANCE = 1e-9  # rad
MAX_ITERATIONS = 30
MAX_STEP = 0.5  # rad: a longer Gauss-Newton step is shortened to this (far from a solution)
DIFFERENCE_STEP = 1e-7  # rad
SINGULAR = 1e-9  # smallest over largest singular value of the Jacobian: singular below
REACHED, NOT_REACHED = "reached", "not reached"
HELD_MOVE = np.radians(0.5)  # rad: a command moving a joint the data held by more is beyond the data there

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class CalibratedRobot:
    """One campaign's sensor under one model, ready to predict and compensate.

    calibration: the robot's side (`prediction.Calibration`, held zero-offsets at their values);
    point (3,) m flange frame, at_marker: whether it is the sensor's marker; setup: registration.*
    sensor_scale.s and sensor_distortion.* posterior means (SI); t_nr (4, 4) the initial registration (robot ->
    sensor); samples: posterior rows (every free parameter, registration and noise.sigma
    included; empty without MCMC); held: {zero-offset: value} the data cannot see, held_tolerance
    (rad) of the controller's marks; gp: the loop's residual GP (robot frame, at the marker);
    absorbed: the held zero-offsets a registration absorbs (the others, e.g. a joint whose axis
    the marker lies on, are unseen in the sensor frame too); near: how near a command is to the
    configurations the fit measured (`robot.nearness`); declared (m): the model error per axis the
    calibration declares (`LoopReport.declared_model_error`: zero where the loop closed), drawn
    independently per axis and command in every bound, as the acceptance test claims it;
    declared_field: the same error as a field over the joints (`LoopReport.declared_field`, the loop
    model's; None: none fitted), drawn where a statistic over commands asks for one arm's field
    (`draw_points(jointly=True)`); tool:
    at a TCP, how the priors split the marker's offset between its mount and the flange
    (`tool_link.ToolSplit`: the TCP's shift, its mean in the positions, drawn in every bound),
    None at the marker."""

    chain: KinematicChain
    calibration: Calibration
    point: np.ndarray
    at_marker: bool
    setup: Mapping[str, float]
    t_nr: np.ndarray
    samples: pd.DataFrame
    held: Mapping[str, float]
    held_tolerance: float
    gp: ResidualGP | None = None
    absorbed: frozenset[str] = frozenset()
    near: Nearness | None = None
    declared: float = 0.0
    tool: ToolSplit | None = None
    declared_field: Hyperparameters | None = None

    @property
    def blocks(self) -> tuple[str, ...]:
        """The model's blocks at this point: at a TCP the marker's offset is not the tool's; with a
        split, the marker_offset block carries the TCP's shift instead (`at_point`)."""
        if self.at_marker:
            return self.calibration.blocks
        own = tuple(b for b in self.calibration.blocks if b != "marker_offset")
        return own + ("marker_offset",) if self.tool is not None else own

    def at_point(self, values: Mapping[str, float]) -> dict[str, float]:
        """Parameter values at this point: at a TCP with a split, the marker offset (absent: 0)
        replaced by the TCP's expected shift given it; unchanged at the marker."""
        if self.at_marker or self.tool is None:
            return dict(values)
        shift = self.tool.mean([values.get(n, 0.0) for n in MARKER_OFFSET])
        return {**values, **dict(zip(MARKER_OFFSET, shift))}

    @property
    def carried_by_marker(self) -> frozenset[str]:
        """The held zero-offsets the posterior's free marker offset carries at the marker
        (`parameter_blocks.carried_by_marker_offset`: the last joint's); none at a TCP."""
        if not self.at_marker:
            return frozenset()
        return carried_by_marker_offset(self.chain.n_joints, self.held, self.samples.columns)

    def held_drawn(self, frame: str) -> list[str]:
        """The held zero-offsets drawn at the marks' tolerance in `frame`: in the sensor frame,
        those no registration absorbs; in either, not one the marker offset carries."""
        return sorted(
            n for n in self.held if (frame == "robot" or n not in self.absorbed) and n not in self.carried_by_marker
        )

    def notes(self, frame: str) -> list[str]:
        """What the user should know about this model, point and frame."""
        out = []
        drawn = self.held_drawn(frame)
        if drawn:
            joints = ", ".join(n.split(".")[-1] for n in drawn)
            out.append(
                f"{frame} frame: the zero-offset of {joints}, which these data do not see, is at the controller's "
                f"mark and drawn at its tolerance ({np.degrees(self.held_tolerance):.3g} deg) in the bounds"
            )
        for name in sorted(self.carried_by_marker):
            out.append(
                f"the zero-offset of {name.split('.')[-1]}, held at the controller's mark, is carried at the marker by "
                "the fitted marker offset (the last joint's turn moves the marker as an offset does): not drawn again"
            )
        if frame == "robot" and self.absorbed:
            out.append(
                "--frame sensor gives positions in this campaign's sensor set-up, where the registration holds "
                f"the zero-offset of {', '.join(n.split('.')[-1] for n in sorted(self.absorbed))}"
            )
        if not self.at_marker and self.tool is not None:
            offset = np.array([self.calibration.values.get(n, 0.0) for n in MARKER_OFFSET])
            out.append(
                "not determined: where the TCP sits on the flange relative to the marker (one marker per row moves "
                f"alike whether the marker's mount or the flange is off); the marker's fitted offset "
                f"({np.linalg.norm(offset) / MM:.3g} mm) is split by the priors, which leave "
                f"{', '.join(f'{v / MM:.2g}' for v in self.tool.std)} mm (flange x, y, z) in every bound"
            )
        elif not self.at_marker and "marker_offset" in self.calibration.blocks:
            out.append("the loop's marker offset was measured at the marker: not applied to a TCP")
        if not self.at_marker and self.gp is not None:
            out.append("the loop's residual GP was measured at the marker: not applied to a TCP")
        if self.declared > 0:
            out.append(
                f"the loop is not closed: the bounds include the model error it declares, {self.declared / MM:.3g} mm "
                "per axis (what it measured beyond the sensor's noise)"
            )
        if self.samples.empty:
            out.append("no posterior samples: no bounds")
        return out

    def predictor(self, q) -> Predictor:
        return Predictor(self.chain, q, self.point, self.blocks, self.calibration.settings)

    def _gp_applies(self) -> bool:
        return self.gp is not None and self.at_marker

    def robot_points(self, q, values: Mapping[str, float] | None = None) -> np.ndarray:
        """Positions (n, 3) m in the robot frame at commands q (n, N) rad (posterior mean by default)."""
        points = self.predictor(q).points(self.at_point(self.calibration.values if values is None else values))
        return points + self.gp.mean(q) if self._gp_applies() else points

    def robot_to_sensor(self, values: Mapping[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(T (4, 4) robot -> sensor, the sensor's linear map (1 + s)(I + D) (3, 3)) at parameter
        values (the posterior mean by default)."""
        values = self.setup if values is None else values
        transform = correction_transforms(np.array([[values.get(n, 0.0) for n in SETUP[:6]]]))[0] @ self.t_nr
        strain = distortion_matrix([values.get(f"sensor_distortion.{p}", 0.0) for p in DISTORTION_PARTS])
        return transform, (1.0 + values.get("sensor_scale.s", 0.0)) * (np.eye(3) + strain)

    def in_frame(self, points, frame: str, values: Mapping[str, float] | None = None) -> np.ndarray:
        """Robot-frame points (..., 3) in `frame` (the sensor's through the fitted registration)."""
        if frame == "robot":
            return np.asarray(points, dtype=float)
        transform, linear = self.robot_to_sensor(values)
        return spatial.transform_points(transform, points) @ linear.T

    def from_sensor(self, points) -> np.ndarray:
        """Sensor-frame points (n, 3) in the calibrated robot frame (posterior mean)."""
        transform, linear = self.robot_to_sensor()
        unmapped = np.linalg.solve(linear, np.asarray(points, dtype=float).T).T
        return spatial.transform_points(spatial.invert(transform), unmapped)

    def draws(self, count: int, frame: str, rng: np.random.Generator) -> tuple[list[dict], np.ndarray]:
        """`count` posterior draws ({name: SI}, every parameter) and their noise sigmas (count,):
        whole sample rows chosen by rng; each held zero-offset is drawn at the controller marks'
        tolerance, in the sensor frame only those no registration absorbs."""
        if self.samples.empty:
            return [], np.zeros(0)
        rows = rng.choice(len(self.samples), count, replace=len(self.samples) < count)
        chosen = self.samples.iloc[rows]
        base = {**self.calibration.values, **self.setup}
        draws = [{**base, **row} for row in chosen.drop(columns=[SIGMA]).to_dict(orient="records")]
        if not self.at_marker and self.tool is not None:
            offsets = np.array([[d.get(n, 0.0) for n in MARKER_OFFSET] for d in draws])
            shifts = self.tool.draw(offsets, rng)
            draws = [{**d, **dict(zip(MARKER_OFFSET, row))} for d, row in zip(draws, shifts)]
        names = self.held_drawn(frame)
        if names:
            shifts = self.held_tolerance * rng.standard_normal((count, len(names)))
            draws = [{**d, **{n: self.held[n] + s for n, s in zip(names, row)}} for d, row in zip(draws, shifts)]
        sigma = np.full(count, self.gp.hyper.noise_std) if self._gp_applies() else chosen[SIGMA].to_numpy(float)
        return draws, sigma

    def draw_points(
        self, q, frame: str, count: int, rng: np.random.Generator, jointly: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """Positions (K, n, 3) in `frame` at commands q for K = count posterior draws (GP draws
        added), and the same with each draw's noise; (0, n, 3) without samples. The residual GP and
        the declared model error are drawn per command (what a per-command bound needs, at any number
        of commands) or, `jointly`, as fields across the commands (`ResidualGP.draws`,
        `residual.model_error_draws`), so that a statistic over them (a p95) is one of an arm's."""
        draws, sigma = self.draws(count, frame, rng)
        if not draws:
            empty = np.zeros((0, len(q), 3))
            return empty, empty
        points = self.predictor(q).points_of_draws(draws)
        if self._gp_applies() and jointly:
            points = points + self.gp.draws(q, count, rng)
        elif self._gp_applies():
            std = np.sqrt(self.gp.variance(q))
            points = points + self.gp.mean(q) + std[None, :, None] * rng.standard_normal(points.shape)
        if self.declared > 0:
            field = self.declared_field if jointly else None
            points = points + model_error_draws(self.declared, field, q, count, rng)
        if frame == "sensor":
            points = np.stack([self.in_frame(p, frame, d) for p, d in zip(points, draws)])
        return points, points + sigma[:, None, None] * rng.standard_normal(points.shape)


# --------------------------------------------------------------------------- from the results


def _setup_values(table: pd.DataFrame) -> dict[str, float]:
    return {str(n): float(v) for n, v in zip(table["parameter"], table["mean"]) if str(n) in SETUP}


def _posterior_rows(
    samples: pd.DataFrame, calibration: Calibration, setup: Mapping[str, float], label: str
) -> pd.DataFrame:
    """The sample columns of every free parameter (robot and set-up) and sigma; empty without samples."""
    if samples is None or samples.empty:
        return pd.DataFrame()
    free = [] if calibration.draws is None else list(calibration.draws.columns)
    names = free + [n for n in setup if n in samples.columns] + [SIGMA]
    require_columns(samples, free + [SIGMA], file=label, of="the posterior samples")
    return samples[names].astype(float).reset_index(drop=True)


def calibrated_robot(
    campaign: Campaign, sensor: str, model: str, results: Mapping, tcp=None, label: str = ""
) -> CalibratedRobot:
    """The calibrated robot of a campaign's sensor from its results (`results.sensor_results`:
    registration, laplace, summary, paper_samples, loop, loop_samples, gp). tcp (3,) m in the
    flange frame, or None for the sensor's marker."""
    if sensor not in campaign.sensors:
        raise InputError(
            f"no sensor {sensor!r} in the campaign (known: {', '.join(campaign.sensors)})",
            file=campaign.name,
            key="sensors",
        )
    if model not in MODELS:
        raise InputError(f"unknown model {model!r} (known: {', '.join(MODELS)})", key="model")
    loop = results["loop"]
    if model == "paper":
        summary = results["summary"]
        calibration = paper_calibration(summary, results["paper_samples"], label)
        setup, samples, gp = _setup_values(summary), results["paper_samples"], None
    else:
        calibration = loop_calibration(loop, results["loop_samples"], label)
        setup = _setup_values(loop.parameters)
        samples, gp = results["loop_samples"], loop_candidate.from_results(results.get("gp"), loop.residual_gp)
    laplace = results["laplace"]
    held, absorbed = laplace.held_zero_offsets, laplace.absorbed_by_registration
    tolerance = loop.held_zero_offset_std
    marker = campaign.sensors[sensor].marker
    point = marker if tcp is None else np.asarray(tcp, dtype=float)
    tool = None if tcp is None else ToolSplit.of(marker, point, *loop.tool_link_stds)
    return CalibratedRobot(
        campaign.chain,
        calibration,
        np.asarray(point, dtype=float),
        tcp is None,
        setup,
        results["registration"].t_nr,
        _posterior_rows(samples, calibration, setup, label),
        held,
        tolerance,
        gp,
        absorbed,
        Nearness.of(
            campaign.chain,
            campaign.sensors[sensor].fit_readings(laplace.outlier_rows),
            marker,
            calibration.linear_joints,
        ),
        loop.declared_model_error(model) or 0.0,
        tool,
        loop.declared_field() if model == "loop" else None,
    )


# --------------------------------------------------------------------------- inputs


def joint_commands(table: pd.DataFrame, chain: KinematicChain, label: str, required: bool = True) -> np.ndarray | None:
    """Joint commands (n, N) rad from columns q1..qN: finite numbers within the joint limits.
    None when no q column is there and they are not `required`."""
    names = [f"q{j + 1}" for j in range(chain.n_joints)]
    present = [n for n in names if n in table.columns]
    if not present and not required:
        return None
    require_columns(table, names, file=label, kind="joint", listed=True)
    q = _numbers(table, names, label)
    for j, name in enumerate(names):
        outside = np.flatnonzero((q[:, j] < chain.lower[j]) | (q[:, j] > chain.upper[j]))
        if len(outside):
            raise InputError(
                f"beyond the joint limits [{chain.lower[j]:.4g}, {chain.upper[j]:.4g}] rad (commands are in rad)",
                file=label,
                key=name,
                rows=outside,
            )
    return q


def targets_or_commands(
    table: pd.DataFrame, chain: KinematicChain, label: str
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(targets (n, 3) m from x, y, z or None, commands (n, N) rad from q1..qN or None) of a
    targets file: target positions with optional seed commands, or nominal commands alone."""
    q = joint_commands(table, chain, label, required=False)
    if {"x", "y", "z"} <= set(table.columns):
        return _numbers(table, ["x", "y", "z"], label), q
    if q is None:
        raise InputError(
            f"neither target positions nor joint commands (got: {', '.join(map(str, table.columns))})",
            file=label,
            key=f"x, y, z or q1..q{chain.n_joints}",
        )
    return None, q


def _numbers(table: pd.DataFrame, names: list[str], label: str) -> np.ndarray:
    if table.empty:
        raise InputError("no rows", file=label)
    for name in names:
        values = pd.to_numeric(table[name], errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise InputError("not a finite number", file=label, key=name, rows=bad)
    return table[names].astype(float).to_numpy()


# --------------------------------------------------------------------------- predict


def _bounds_mm(points_draws: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """`bounds.bound_at_points` (n,) mm of draws (K, n, 3) m about reference (n, 3) m."""
    return bound_at_points(np.linalg.norm(points_draws - reference, axis=-1)) / MM


def predict(robot: CalibratedRobot, q, frame: str, count: int, rng: np.random.Generator) -> pd.DataFrame:
    """Predicted positions at commands q (n, N) rad in `frame` (see the module docstring): one row
    per command with x, y, z (m), nominal_x..z (m), correction_mm, bound95_mm, bound95_with_noise_mm."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    points = robot.in_frame(robot.robot_points(q), frame)
    nominal = ForwardKinematics(robot.chain, q).points(robot.point)
    if frame == "sensor":
        nominal = spatial.transform_points(robot.t_nr, nominal)
    draws, noisy = robot.draw_points(q, frame, count, rng)
    table = pd.DataFrame({"row": np.arange(len(q))})
    for j in range(q.shape[1]):
        table[f"q{j + 1}"] = q[:, j]
    for k, axis in enumerate("xyz"):
        table[axis] = points[:, k]
    for k, axis in enumerate("xyz"):
        table[f"nominal_{axis}"] = nominal[:, k]
    table["correction_mm"] = np.linalg.norm(points - nominal, axis=1) / MM
    table["bound95_mm"] = _bounds_mm(draws, points)
    table["bound95_with_noise_mm"] = _bounds_mm(noisy, points)
    return with_nearness(table, robot.near, q)


def with_nearness(table: pd.DataFrame, near: Nearness | None, q) -> pd.DataFrame:
    """table with `distance_to_data_mm` (how far the marker moves, at most to first order, from the
    nearest configuration the fit measured), `near_data` (within the data's own spacing: where
    the bounds are claimed) and `determined` with `not_determined_why`, per command q (n, N):
    determined where near the data and no joint the data held (never moved) is moved by more
    than `HELD_MOVE`; elsewhere the bound is the priors', as the certificate says of the claim
    across the joint limits, and the why names the held joints moved, else the joints read a turn
    from the data in a model that corrects in proportion to the reading (near on the circle only:
    `Nearness.turns`), else the distance. Unchanged without a nearness."""
    if near is None:
        return table
    q = np.atleast_2d(np.asarray(q, dtype=float))
    distance = near.distance(q)
    held = near.held_joints()
    moves = near.differences(q, near.measured[0])  # a held joint's value is its first reading
    moved = [
        [
            f"q{j + 1} held at {np.degrees(v):.3g} deg in the data, here {np.degrees(row[j]):.3g}"
            for j, v in held.items()
            if abs(move[j]) > HELD_MOVE
        ]
        for row, move in zip(q, moves)
    ]
    inside = distance <= near.radius
    turned = _turned(near, q, inside)
    table["distance_to_data_mm"] = distance / MM
    table["near_data"] = inside
    table["determined"] = inside & np.array([not m for m in moved], dtype=bool)
    table["not_determined_why"] = [
        "" if ok else _why_not_determined(m or t, d, near.radius)
        for ok, m, t, d in zip(table["determined"], moved, turned, distance)
    ]
    return table


def _turned(near: Nearness, q: np.ndarray, inside: np.ndarray) -> list[list[str]]:
    """Per command, the joints it reads a turn from the nearest measured configuration on the
    circle, where the model corrects in proportion to the reading and only the circle finds the
    command near the data: 'q1 reads 340 deg here, one turn from -20 deg in the data (near on the
    circle only): a joint scale corrects in proportion to the reading'."""
    out: list[list[str]] = [[] for _ in q]
    if not near.linear:
        return out
    circle = near.on_circle()
    beyond = np.flatnonzero(~inside & (circle.distance(q) <= near.radius))
    turns = near.turns(q[beyond])
    for i, row_turns in zip(beyond, turns):
        for j in np.flatnonzero(row_turns):
            measured = q[i, j] - 2.0 * np.pi * row_turns[j]
            count = "one turn" if abs(row_turns[j]) == 1 else f"{abs(row_turns[j])} turns"
            out[i].append(
                f"q{j + 1} reads {np.degrees(q[i, j]):.4g} deg here, {count} from about {np.degrees(measured):.4g} deg "
                "in the data (near on the circle only): a joint scale corrects in proportion to the reading"
            )
    return out


def _why_not_determined(named: list[str], distance: float, radius: float) -> str:
    """Why a command's bound is not determined: the joints `named` (held joints moved, or joints
    read a turn away), else how far beyond the data."""
    if not np.isfinite(distance):
        return "not determined: no configuration to compare (not reached)"
    where = (
        "; ".join(named)
        or f"{distance / MM:.3g} mm from the measured configurations (their spacing {radius / MM:.3g} mm)"
    )
    return f"not determined: {where}: the bound here is the priors', not a measurement"


# --------------------------------------------------------------------------- inverse kinematics


@dataclass(frozen=True)
class Solution:
    """Joint commands (n, N) rad, whether each row converged (n,), its final residual (n,) in m
    (position) and rad (orientation), and whether the Jacobian was singular there (n,)."""

    q: np.ndarray
    converged: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    singular: np.ndarray


def nearest_solution(evaluate: Callable, targets, q_anchor, rotations=None) -> Solution:
    """Commands q (n, N) with evaluate(q) = (points (n, 3), flange rotations (n, 3, 3)) on the
    targets (n, 3) and, when given, on the rotations (n, 3, 3), nearest to q_anchor (n, N): the
    Gauss-Newton projection of the module docstring, row by row converged."""
    targets, anchor = np.asarray(targets, dtype=float), np.atleast_2d(np.asarray(q_anchor, dtype=float))
    n, n_joints = anchor.shape

    def residual(points, frames, rows):
        r = points - targets[rows]
        if rotations is None:
            return r
        relative = np.einsum("nji,njk->nik", rotations[rows], frames)
        return np.hstack([r, Rotation.from_matrix(relative).as_rotvec()])

    q = anchor.copy()
    active = np.arange(n)
    converged, singular = np.zeros(n, bool), np.zeros(n, bool)
    errors = np.full((n, 2), np.inf)
    for _ in range(MAX_ITERATIONS + 1):
        if not len(active):
            break
        steps = [q[active]] + [q[active] + DIFFERENCE_STEP * np.eye(n_joints)[j] for j in range(n_joints)]
        points, frames = evaluate(np.vstack(steps))
        m = len(active)
        parts = [
            residual(points[k * m : (k + 1) * m], None if frames is None else frames[k * m : (k + 1) * m], active)
            for k in range(n_joints + 1)
        ]
        r = parts[0]
        errors[active, 0] = np.linalg.norm(r[:, :3], axis=1)
        errors[active, 1] = np.linalg.norm(r[:, 3:], axis=1) if r.shape[1] > 3 else 0.0
        done = (errors[active, 0] < POSITION_TOLERANCE) & (errors[active, 1] < ORIENTATION_TOLERANCE)
        converged[active[done]] = True
        jacobian = np.stack([(p - r) / DIFFERENCE_STEP for p in parts[1:]], axis=-1)  # (m, 3 or 6, N)
        values = np.linalg.svd(jacobian, compute_uv=False)
        singular[active] = values[:, -1] < SINGULAR * values[:, 0] if jacobian.shape[1] <= n_joints else False
        keep = ~done
        active, jacobian, r = active[keep], jacobian[keep], r[keep]
        if not len(active):
            break
        offset = q[active] - anchor[active]
        rhs = np.einsum("mij,mj->mi", jacobian, offset) - r
        target_q = anchor[active] + np.einsum("mij,mj->mi", np.linalg.pinv(jacobian), rhs)
        step = target_q - q[active]
        length = np.linalg.norm(step, axis=1, keepdims=True)
        q[active] += step * np.minimum(1.0, MAX_STEP / np.maximum(length, 1e-300))
    return Solution(q, converged, errors[:, 0], errors[:, 1], singular)


def _nominal_evaluate(chain: KinematicChain, point) -> Callable:
    def evaluate(q):
        poses = ForwardKinematics(chain, q).flange_poses()
        return poses[:, :3, :3] @ point + poses[:, :3, 3], poses[:, :3, :3]

    return evaluate


def _calibrated_evaluate(robot: CalibratedRobot) -> Callable:
    def evaluate(q):
        return robot.robot_points(q), robot.predictor(q).flange_poses(robot.calibration.values)[:, :3, :3]

    return evaluate


def _why_not(solution: Solution, rows, chain: KinematicChain, what: str) -> dict[int, str]:
    """Reasons {row: text} of the rows that did not converge or leave the joint limits."""
    reasons = {}
    for i in rows:
        if not solution.converged[i]:
            cause = "at a singular configuration" if solution.singular[i] else "out of reach"
            turned = solution.orientation_error[i]
            reasons[i] = (
                f"{what}: {cause}: no convergence, closest {solution.position_error[i] / MM:.3g} mm"
                + (f", {np.degrees(turned):.3g} deg" if turned > 0 else "")
                + " away"
            )
            continue
        below, above = chain.lower - solution.q[i], solution.q[i] - chain.upper
        beyond = np.maximum(below, above)
        if np.any(beyond > 0):
            j = int(np.argmax(beyond))
            reasons[i] = f"{what}: joint {j + 1} beyond its limits by {np.degrees(beyond[j]):.3g} deg"
    return reasons


def _seeds(targets_nominal, candidates, chain: KinematicChain, point) -> np.ndarray:
    """Per target, the candidate configuration (rows of candidates) whose nominal point is nearest."""
    points = ForwardKinematics(chain, candidates).points(point)
    block = max(1, 2**20 // len(points))  # targets per block: memory bounded whatever the campaign's size
    nearest = [
        np.argmin(np.linalg.norm(targets_nominal[start : start + block, None, :] - points[None], axis=-1), axis=1)
        for start in range(0, len(targets_nominal), block)
    ]
    return candidates[np.concatenate(nearest)] if nearest else candidates[:0]


def _compensated_table(chain, q, q0, t_frame, reached, no_nominal, reasons) -> pd.DataFrame:
    """`compensate`'s table before its errors and bounds: row, status, reason, targets, commands."""
    n = len(q0)
    table = pd.DataFrame(
        {
            "row": np.arange(n),
            "status": np.where(reached, REACHED, NOT_REACHED),
            "reason": [reasons.get(i, "") for i in range(n)],
        }
    )
    for k, axis in enumerate("xyz"):
        table[f"target_{axis}"] = t_frame[:, k]
    for j in range(chain.n_joints):
        table[f"q{j + 1}"] = np.where(reached, q[:, j], np.nan)
    for j in range(chain.n_joints):
        table[f"nominal_q{j + 1}"] = np.where(no_nominal, np.nan, q0[:, j])
    table["largest_change_deg"] = np.nan
    for column in ("error_mm", "bound95_mm", "bound95_with_noise_mm", "nominal_error_mm"):
        table[column] = np.nan
    return table


def _fill_errors(table: pd.DataFrame, robot: CalibratedRobot, frame: str, commands, at, drawing) -> None:
    """The errors and 95 % bounds of the reached rows `at` of `compensate`'s table: commands are
    (q, nominal q0, targets) at those rows; drawing is (posterior draws, rng)."""
    q, q0, target = commands
    count, rng = drawing
    table.loc[at, "largest_change_deg"] = np.degrees(np.abs(q - q0).max(axis=1))
    points = robot.in_frame(robot.robot_points(q), frame)
    draws, noisy = robot.draw_points(q, frame, count, rng)
    table.loc[at, "error_mm"] = np.linalg.norm(points - target, axis=1) / MM
    table.loc[at, "bound95_mm"] = _bounds_mm(draws, target)
    table.loc[at, "bound95_with_noise_mm"] = _bounds_mm(noisy, target)
    table.loc[at, "nominal_error_mm"] = (
        np.linalg.norm(robot.in_frame(robot.robot_points(q0), frame) - target, axis=1) / MM
    )


def compensate(
    robot: CalibratedRobot,
    frame: str,
    count: int,
    rng: np.random.Generator,
    *,
    commands=None,
    targets=None,
    seeds=None,
    candidates=None,
) -> pd.DataFrame:
    """Compensated joint commands (see the module docstring), from nominal `commands` (n, N) rad or
    from `targets` (n, 3) m in `frame` with optional `seeds` (n, N) rad, else the nearest of
    `candidates` (m, N) rad (the campaign's optimization configurations). One row per input row:
    status, reason, target_x..z (m, frame), q1..qN, nominal_q1..qN (rad), largest_change_deg,
    error_mm, bound95_mm, bound95_with_noise_mm, nominal_error_mm. Each stage is logged (INFO)."""
    chain, point = robot.chain, robot.point
    nominal = _nominal_evaluate(chain, point)
    reasons: dict[int, str] = {}  # rows not reached
    if commands is not None:
        q0 = np.atleast_2d(np.asarray(commands, dtype=float))
        t_nominal, r0 = nominal(q0)
        no_nominal = np.zeros(len(q0), bool)
    else:
        t = np.atleast_2d(np.asarray(targets, dtype=float))
        t_nominal = t if frame == "robot" else spatial.transform_points(spatial.invert(robot.t_nr), t)
        start = np.asarray(seeds, dtype=float) if seeds is not None else _seeds(t_nominal, candidates, chain, point)
        log.info("%d targets: inverse kinematics on the nominal model", len(t))
        found = nearest_solution(lambda q: (nominal(q)[0], None), t_nominal, start)
        reasons.update(_why_not(found, range(len(t)), chain, "nominal model"))
        q0 = found.q
        no_nominal = np.isin(np.arange(len(q0)), list(reasons))
        r0 = nominal(q0)[1]
    n = len(q0)
    # the nominal intent (robot frame of the nominal cell) in the calibrated robot frame
    if frame == "robot":
        t_robot, r_robot, t_frame = t_nominal, r0, t_nominal
    else:
        t_frame = spatial.transform_points(robot.t_nr, t_nominal)
        transform, _ = robot.robot_to_sensor()
        t_robot = robot.from_sensor(t_frame)
        r_robot = np.einsum("ji,jk,nkl->nil", transform[:3, :3], robot.t_nr[:3, :3], r0)
    ok = np.array([i not in reasons for i in range(n)])
    log.info("%d commands: inverse kinematics on the calibrated model", int(ok.sum()))
    solution = nearest_solution(_calibrated_evaluate(robot), t_robot[ok], q0[ok], r_robot[ok])
    rows = np.flatnonzero(ok)
    reasons.update(
        {rows[k]: text for k, text in _why_not(solution, range(len(rows)), chain, "calibrated model").items()}
    )
    q = np.full_like(q0, np.nan)
    q[rows] = solution.q
    reached = np.array([i not in reasons for i in range(n)])

    table = _compensated_table(chain, q, q0, t_frame, reached, no_nominal, reasons)
    if reached.any():
        at = np.flatnonzero(reached)
        log.info("%d commands reached: bounds from %d posterior draws", len(at), count)
        _fill_errors(table, robot, frame, (q[at], q0[at], t_frame[at]), at, (count, rng))
    return with_nearness(table, robot.near, q)  # a target not reached: no distance, not near


def near_summary(table: pd.DataFrame) -> str:
    """'; 12 of 40 commands far from the measured configurations (near_data False: there the bound is
    the model's and its priors', not measured)' or ''."""
    if "near_data" not in table.columns or table["near_data"].all():
        return ""
    far = int((~table["near_data"].astype(bool)).sum())
    return (
        f"; {far} of {len(table)} commands far from the measured configurations (near_data False: there the bound "
        "is the model's and its priors', not measured)"
    )


def not_reached_summary(table: pd.DataFrame) -> str:
    """'3 of 40 targets not reached (rows 2, 7, 9): see the column reason' or ''."""
    rows = table.loc[table["status"] != REACHED, "row"].tolist()
    if not rows:
        return ""
    return f"{len(rows)} of {len(table)} targets not reached ({format_rows(rows)}): see the column reason"
