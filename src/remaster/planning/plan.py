"""`remaster plan`: the planner's decisions, from options and what the command line has read.

Two planners (docs/planning.md): the paper's (`paper_plan`: Latin-hypercube poses, every inverse
kinematics solution, joint 3 held) and the workspace design (`workspace_plan`: the configurations
that most reduce the calibrated model's predicted error across the workspace). The workspace design
starts either from the nominal robot and its priors (`nominal_start`) or from a calibrated campaign
(`campaign_start`: its measured rows, fitted noise and, for the robust criterion, its residual GP).
Which noise a design assumes, which rows a campaign contributes and where its sensor stands are
decided here, not in the command line, which only reads and writes files.

SI inside (m, rad); options given in mm are converted once, here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import spatial
from ..errors import InputError
from ..robot import planning, registration
from ..robot.ik import SRSInverseKinematics
from ..robot.kinematics import ForwardKinematics, KinematicChain
from . import design, design_posterior, plan_inputs, robust_design
from .design_figures import bound_curve

WORKSPACE = "workspace"
ISO9283 = "iso9283"


@dataclass(frozen=True)
class PlanOptions:
    """The options of `remaster plan` (docs/cli.md), as the command line parsed them (mm where named)."""

    objective: str = "paper"
    criterion: str = "workspace"
    statistic: str = "p95"
    exchange: bool = False
    budget: int | None = None
    target_mm: float | None = None
    discrepancy_mm: float | None = None
    noise_mm: float = 0.01
    evaluation: int = design.EVALUATION_CONFIGURATIONS
    workspace: str = "limits"
    candidates: str = "60"
    set: str = "optimization"
    poses: int | None = None
    configurations: int | None = None
    q3: float = 0.0
    link_radius: float = 0.06
    floor: float = 0.0
    marker: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_origin: tuple[float, float, float] | None = None
    from_results: bool = False
    cube_centre: tuple[float, float, float] | None = None
    cube_edge: float | None = None
    cycles: int = 30

    @property
    def workspace_design(self) -> bool:
        """A workspace design: asked for, or the next configurations of a calibrated campaign."""
        return self.objective == WORKSPACE or self.from_results

    @property
    def collision(self) -> planning.CollisionModel:
        return planning.CollisionModel(link_radius=self.link_radius, floor_height=self.floor)

    def candidate_count(self) -> int | None:
        """--candidates as a number of poses (None when it names a file)."""
        try:
            value = int(self.candidates)
        except ValueError:
            return None
        if value < 1:
            raise InputError(f"must be at least 1 or a CSV file, got {value}", key="--candidates")
        return value


def check_options(options: PlanOptions) -> None:
    """InputError for options that do not go together (docs/bad-input.md)."""
    if options.exchange and options.criterion != "workspace":
        raise InputError(f"the exchange improves the workspace criterion, not {options.criterion}", key="--exchange")
    if options.discrepancy_mm is not None and options.criterion != robust_design.CRITERION:
        raise InputError("a discrepancy is the robust criterion's: add --criterion robust", key="--discrepancy-mm")
    cube = {"--cube-centre": options.cube_centre is not None, "--cube-edge": options.cube_edge is not None}
    if options.objective == ISO9283:
        missing = [option for option, given in cube.items() if not given]
        if missing:
            raise InputError(
                "the ISO 9283 pose test needs its cube: --cube-centre X Y Z and --cube-edge E (m)", key=missing[0]
            )
        if options.cube_edge <= 0:
            raise InputError(f"must be a positive length (m), got {options.cube_edge:g}", key="--cube-edge")
    elif any(cube.values()):
        raise InputError("a cube is the ISO 9283 pose test's: add --objective iso9283", key="--objective")
    if options.workspace_design:
        if options.budget is None and options.target_mm is None:
            raise InputError("a workspace design needs --budget N, --target-mm X or both", key="--budget")
        return
    workspace_only = {
        "--criterion": options.criterion != "workspace",
        "--discrepancy-mm": options.discrepancy_mm is not None,
        "--exchange": options.exchange,
        "--budget": options.budget is not None,
        "--target-mm": options.target_mm is not None,
    }
    given = [option for option, used in workspace_only.items() if used]
    if given:
        raise InputError(
            f"{', '.join(given)}: the workspace design's, not the paper planner's: add --objective workspace",
            key="--objective",
        )


def sensor_origin_from_points(chain: KinematicChain, points: pd.DataFrame, marker, label: str) -> np.ndarray:
    """The sensor's origin (3,) m in the robot base frame from a three-point registration as in the
    paper: points has q1..qN (rad) and the marker measured by the sensor x, y, z (m)."""
    joints = [f"q{j + 1}" for j in range(chain.n_joints)]
    missing = [c for c in joints + ["x", "y", "z"] if c not in points.columns]
    if missing:
        raise InputError(f"missing columns {', '.join(missing)}", file=label)
    robot = ForwardKinematics(chain, points[joints].to_numpy(float)).points(marker)
    t_nr = registration.three_point(robot, points[["x", "y", "z"]].to_numpy(float))
    return np.linalg.inv(t_nr)[:3, 3]


@dataclass(frozen=True)
class PaperPlan:
    """The paper planner's configurations (q1..qN in rad and qN_deg) and a line saying what they are."""

    table: pd.DataFrame
    summary: str


def paper_plan(chain: KinematicChain, origin, options: PlanOptions, rng: np.random.Generator) -> PaperPlan:
    """The paper's planner for `options.set` with the sensor at `origin` (3,) m."""
    if options.candidate_count() is None:
        raise InputError("a file of candidates needs --objective workspace", key="--candidates")
    sight = planning.SightLine(origin, np.asarray(options.marker, dtype=float))
    plan = planning.plan_set(
        chain,
        options.set,
        origin,
        [sight],
        rng,
        size=planning.SetSize(options.candidate_count(), options.poses, options.configurations),
        model=options.collision,
        q3=options.q3,
    )
    table = plan.table.copy()
    for j in range(chain.n_joints):
        table[f"q{j + 1}_deg"] = np.degrees(table[f"q{j + 1}"])
    summary = (
        f"{len(table)} configurations of {table['pose'].nunique()} poses from "
        f"{plan.candidates} candidate poses; discarded: {plan.discarded}"
    )
    return PaperPlan(table, summary)


def iso9283_plan(chain: KinematicChain, origin, options: PlanOptions) -> PaperPlan:
    """The ISO 9283 pose test with the sensor at `origin` (3,) m: the five points P1..P5 of the
    cube `options.cube_centre`, `cube_edge` (`planning.iso9283_points`), the flange turned towards
    the sensor (one orientation for all, `planning.cube_orientation`), each reached by its first
    usable inverse-kinematics solution, joint 3 at `options.q3`, and visited P1..P5 in turn for
    `options.cycles` cycles (the standard asks for 30): each configuration is commanded once per
    cycle, so that the campaign's ISO 9283 table gives AP over the cycles and RP for every pose.
    Every row is its own pose of the campaign format (pose = cycle x 5 + point); `iso_pose` and
    `cycle` name them. A point no solution reaches is refused with the reasons."""
    centre = np.asarray(options.cube_centre, dtype=float)
    sight = planning.SightLine(origin, np.asarray(options.marker, dtype=float))
    rotation = planning.cube_orientation([centre], origin)
    solver = SRSInverseKinematics(chain)
    reached = []
    for k, point in enumerate(planning.iso9283_points(centre, float(options.cube_edge))):
        flange = spatial.homogeneous(rotation, point)
        solutions, reasons = planning.usable_solutions(chain, flange, [sight], options.collision, options.q3, solver)
        if len(solutions) == 0:
            why = ", ".join(f"{n} {r}" for r, n in reasons.items() if n) or "no inverse-kinematics solution"
            raise InputError(
                f"ISO 9283 point P{k + 1} at {np.round(point, 3).tolist()} m is not reachable with the flange "
                f"towards the sensor ({why}): move or shrink the cube",
                key="--cube-centre",
            )
        reached.append(solutions[0])
    cycles, points = int(options.cycles), len(reached)
    q = np.tile(np.array(reached), (cycles, 1))
    table = pd.DataFrame(
        {
            "set": options.set,
            "pose": np.arange(cycles * points, dtype=np.int64),
            "solution": np.zeros(cycles * points, dtype=np.int64),
            "cycle": np.repeat(np.arange(1, cycles + 1), points),
            "iso_pose": np.tile([f"P{k + 1}" for k in range(points)], cycles),
        }
    )
    for j in range(chain.n_joints):
        table[f"q{j + 1}"] = q[:, j]
    for j in range(chain.n_joints):
        table[f"q{j + 1}_deg"] = np.degrees(q[:, j])
    summary = (
        f"ISO 9283 pose test: P1..P{points} of a {options.cube_edge:g} m cube, {cycles} cycles ({len(table)} rows)"
    )
    return PaperPlan(table, summary)


@dataclass(frozen=True)
class DesignStart:
    """What a workspace design starts from: the error model (`design_posterior.ErrorModel`) and its
    information before any new row, the rows already measured (n, N) rad, the marker (3,) m, the
    sensor's origin (3,) m, the campaign's residual GP when its loop found structure, and a note."""

    chain: KinematicChain
    model: object
    information: np.ndarray
    measured: np.ndarray
    marker: np.ndarray
    origin: np.ndarray
    measured_gp: dict | None = None
    note: str = ""


def nominal_start(chain: KinematicChain, origin, options: PlanOptions, priors) -> DesignStart:
    """A new campaign: the complete error model at the nominal chain, its priors, the stated noise."""
    marker = np.asarray(options.marker, dtype=float)
    t_nr = np.eye(4)
    t_nr[:3, 3] = -origin  # the sensor's orientation does not change a position bound's size
    if not options.noise_mm > 0:
        raise InputError(f"must be > 0 mm, got {options.noise_mm}", key="--noise-mm")
    model = design_posterior.complete_error_model(chain, marker, t_nr, priors, options.noise_mm * 1e-3)
    return DesignStart(chain, model, model.prior_information(), np.zeros((0, chain.n_joints)), marker, origin)


def campaign_start(campaign, sensor, found: dict, options: PlanOptions, priors) -> DesignStart:
    """The next configurations of a calibrated campaign: its measured rows (gross errors and outliers
    excluded) as the prior information, at the noise the loop fitted. found: the sensor's
    'registration', 'laplace' and 'loop' results."""
    loop = found["loop"]
    gross = loop.gross_errors.get("optimization", []) if loop.gross_errors else []
    exclude = sorted(set(found["laplace"].outlier_rows) | set(int(r) for r in gross))
    chain = campaign.chain
    measured_gp = loop.residual_gp if loop.residual_gp and loop.residual_gp.get("structure_found") else None
    # the parametric fit's sigma holds the discrepancy the GP found: with the GP as the robust
    # criterion's discrepancy, the noise is the GP's own, or the discrepancy would count twice
    robust_gp = measured_gp is not None and options.criterion == robust_design.CRITERION
    sigma = float(measured_gp["hyperparameters"]["noise_std_m"]) if robust_gp else loop.sigma_after
    t_nr = found["registration"].t_nr
    start = plan_inputs.campaign_prior(chain, sensor, t_nr, sigma, priors, exclude=exclude)
    measured = sensor.table.loc[start.rows, list(sensor.joint_columns)].to_numpy(dtype=float)
    origin = campaign_sensor_origin(options, chain, t_nr, sensor, measured)
    moved = ", ".join(f"q{j + 1} {f:.0%}" for j, f in enumerate(start.moved_fraction))
    note = f"{len(start.rows)} measured rows; share of each joint's range moved: {moved}"
    return DesignStart(chain, start.model, start.information, measured, sensor.marker, origin, measured_gp, note)


def campaign_sensor_origin(options: PlanOptions, chain, t_nr, sensor, measured) -> np.ndarray:
    """Where a calibrated campaign's sensor stands in the robot base frame (m), for the sight lines of
    generated candidates: --sensor-origin when given, else the registration's. A campaign whose
    coordinates were moved to the robot's frame before it was published registers to about the
    identity, which puts the sensor at the robot's base: if none of its own measured rows would be
    seen from there, the registration does not say where the sensor was, and a generated design would
    be checked against the wrong sight line."""
    if options.sensor_origin is not None:
        return np.asarray(options.sensor_origin, dtype=float)
    origin = np.linalg.inv(t_nr)[:3, 3]
    if options.candidate_count() is None or not len(measured):
        return origin  # candidates given: no sight line is checked
    seen = planning.marker_visible(chain, measured, planning.SightLine(origin, sensor.marker), options.collision)
    if not seen.any():
        raise InputError(
            f"the registration puts the sensor at ({origin[0]:.3f}, {origin[1]:.3f}, {origin[2]:.3f}) m in the "
            f"robot frame, from where none of the campaign's {len(measured)} measured rows would be seen: its "
            "coordinates are not the sensor's own (moved to the robot's frame?); give the sensor's position "
            "--sensor-origin X Y Z (m, robot base frame), or the candidates --candidates FILE",
            key="--sensor-origin",
        )
    return origin


def discrepancy_prior(options: PlanOptions, evaluation, sigma: float, measured_gp: dict | None):
    """The robust criterion's discrepancy prior: a campaign's residual GP when its loop found structure
    (--from-results; a joint it never turned takes its workspace range), else the default (the
    sensor's noise as signal, each joint's workspace range as lengthscale); --discrepancy-mm sets the
    signal std of either."""
    if options.discrepancy_mm is not None and not options.discrepancy_mm >= 0:
        raise InputError(f"must be >= 0 mm, got {options.discrepancy_mm}", key="--discrepancy-mm")
    if measured_gp is not None:
        found = robust_design.discrepancy_of(measured_gp["hyperparameters"], evaluation)
        signal = found.signal_std if options.discrepancy_mm is None else options.discrepancy_mm * 1e-3
        return robust_design.Discrepancy(found.lengthscales, signal)
    signal = sigma if options.discrepancy_mm is None else options.discrepancy_mm * 1e-3
    return robust_design.workspace_discrepancy(evaluation, signal)


@dataclass(frozen=True)
class WorkspacePlan:
    """A workspace design: the chosen configurations (`design.chosen_table`), the bound against the
    number chosen (`design.bound_table`), its figure, and lines saying what was done."""

    chosen: pd.DataFrame
    bounds: pd.DataFrame
    figure: object
    notes: list[str]
    summary: str


def workspace_plan(
    start: DesignStart,
    options: PlanOptions,
    rng: np.random.Generator,
    candidate_table: pd.DataFrame | None = None,
    label: str = "",
) -> WorkspacePlan:
    """The workspace design from `start`: candidates from `candidate_table` (a CSV of configurations,
    named `label` in messages) or generated from the sensor's sight line, the bound taken at
    `options.evaluation` configurations across the limits or the candidates' ranges."""
    chain, model, information, measured = start.chain, start.model, start.information, start.measured
    notes = []
    if candidate_table is not None:
        candidates = plan_inputs.table_candidates(candidate_table, chain, label)
    else:
        candidates = plan_inputs.generated_candidates(
            chain,
            start.origin,
            start.marker,
            rng,
            poses=options.candidate_count(),
            collision=options.collision,
            set_name=options.set,
        )
    q = plan_inputs.configurations(candidates, chain.n_joints)
    within = q if options.workspace == "candidates" else None
    evaluation = design.evaluation_configurations(chain, options.evaluation, rng, within=within)
    target = None if options.target_mm is None else options.target_mm * 1e-3
    if options.criterion == robust_design.CRITERION:
        if len(measured) > robust_design.MAX_MEASURED_ROWS:
            raise InputError(
                f"the campaign has {len(measured)} measured rows; the robust criterion takes at most "
                f"{robust_design.MAX_MEASURED_ROWS} (their discrepancy kernel grows as the rows squared): "
                "use --criterion workspace",
                key="--criterion",
            )
        discrepancy = discrepancy_prior(options, evaluation, model.sigma, start.measured_gp)
        notes.append(f"discrepancy prior: {discrepancy.report()}")
        chosen = robust_design.robust_design(
            model.whitened_jacobian(q),
            q,
            model.jacobian(evaluation),
            evaluation,
            information,
            discrepancy,
            model.sigma,
            budget=options.budget,
            target=target,
            measured_jacobian=model.whitened_jacobian(measured),
            q_measured=measured,
        )
    else:
        chosen = design.greedy_design(
            model.whitened_jacobian(q),
            model.jacobian(evaluation),
            information,
            budget=options.budget,
            target=target,
            criterion=options.criterion,
            statistic=options.statistic,
        )
    if options.exchange:
        chosen = design.exchange_design(chosen, model.whitened_jacobian(q), model.jacobian(evaluation), information)
    bounds = design.bound_table(chosen)
    figure = bound_curve(bounds, f"{len(chosen.chosen)} configurations ({options.criterion})", options.target_mm)
    what = (
        f"expected RMS error per axis across the workspace, with the discrepancy, {chosen.final_bound_mm:.4g} mm"
        if chosen.statistic == "rms"
        else f"predicted workspace 95 % bound {chosen.final_bound_mm:.4g} mm ({options.statistic})"
    )
    summary = (
        f"{len(chosen.chosen)} of {len(candidates)} candidate configurations ({options.criterion}; stopped: "
        f"{chosen.stopped}); {what}"
    )
    return WorkspacePlan(design.chosen_table(candidates, chosen, chain.n_joints), bounds, figure, notes, summary)
