"""Command line: `remaster plan`, `remaster program`, `remaster simulate`, `remaster import`,
`remaster predict` and `remaster compensate`.

Each subcommand reads its inputs, calls the library and writes its outputs; errors in the input
end with a message naming the file, key or column and rows, and exit status 2 (nothing written).
`remaster compensate` exits with status 3 when it wrote its table but some targets were not
reached (each such row says why).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .analysis import compensation, design, design_discrepancy, design_inputs, design_posterior
from .campaigns import importer, scenario
from .campaigns.folders import import_campaign, read_campaign, write_campaign
from .campaigns.robot_model import load_chain
from .errors import InputError, RemasterError
from .files import read_csv, read_yaml, write_csv, write_figure, write_json, write_text
from .reporting import figures_design
from .results import sensor_folder, sensor_results
from .robot import joint_tour, planning, priors, programs, registration
from .robot.kinematics import ForwardKinematics

DEFAULT_SCENARIOS = Path("data") / "simulation"
NOT_REACHED_STATUS = 3


def _simulate(args: argparse.Namespace) -> None:
    paths = [Path(p) for p in args.scenarios] or sorted(DEFAULT_SCENARIOS.glob("*.yaml"))
    if not paths:
        raise RemasterError(f"no scenario given and none found in {DEFAULT_SCENARIOS}")
    for path in paths:
        base = read_yaml(path)
        chain = load_chain(base["robot"], path.parent, Path.cwd(), source=str(path), name=base["name"])
        for spec, seed in scenario.copies(base, args.copies, args.seed):
            campaign = scenario.simulate(spec, chain, seed=seed)
            folder = write_campaign(Path(args.raw_dir) / spec["name"], campaign.metadata, campaign.tables)
            truth = write_json(Path(args.truth_dir) / f"{spec['name']}.json", campaign.truth)
            rows = {name: len(t) for name, t in campaign.tables.items()}
            print(f"{path}: wrote {folder} ({rows}) and {truth}")


def _sensor_origin(args: argparse.Namespace, chain) -> np.ndarray:
    if args.sensor_origin is not None:
        return np.asarray(args.sensor_origin, dtype=float)
    if args.registration_points is None:
        raise InputError("needs the sensor: --sensor-origin X Y Z or --registration-points CSV", key="--sensor-origin")
    points = read_csv(args.registration_points)
    joints = [f"q{j + 1}" for j in range(chain.n_joints)]
    missing = [c for c in joints + ["x", "y", "z"] if c not in points.columns]
    if missing:
        raise RemasterError(f"{args.registration_points}: missing columns {', '.join(missing)}")
    robot = ForwardKinematics(chain, points[joints].to_numpy(float)).points(args.marker)
    t_nr = registration.three_point(robot, points[["x", "y", "z"]].to_numpy(float))
    return np.linalg.inv(t_nr)[:3, 3]


def _plan(args: argparse.Namespace) -> None:
    if args.exchange and args.criterion != "workspace":
        raise InputError(f"the exchange improves the workspace criterion, not {args.criterion}", key="--exchange")
    if args.discrepancy_mm is not None and args.criterion != design_discrepancy.CRITERION:
        raise InputError("a discrepancy is the robust criterion's: add --criterion robust", key="--discrepancy-mm")
    if args.objective == "workspace" or args.from_results is not None:
        _plan_workspace(args)
        return
    workspace_only = {
        "--criterion": args.criterion != "workspace",
        "--discrepancy-mm": args.discrepancy_mm is not None,
        "--exchange": args.exchange,
        "--budget": args.budget is not None,
        "--target-mm": args.target_mm is not None,
    }
    given = [option for option, used in workspace_only.items() if used]
    if given:
        raise InputError(
            f"{', '.join(given)}: the workspace design's, not the paper planner's: add --objective workspace",
            key="--objective",
        )
    chain = _plan_chain(args)
    origin = _sensor_origin(args, chain)
    if _candidate_count(args) is None:
        raise InputError("a file of candidates needs --objective workspace", key="--candidates")
    rng = np.random.default_rng(args.seed)
    model = planning.CollisionModel(link_radius=args.link_radius, floor_height=args.floor)
    sight = planning.SightLine(origin, np.asarray(args.marker, dtype=float))
    plan = planning.plan_set(
        chain,
        args.set,
        origin,
        [sight],
        rng,
        candidates=_candidate_count(args),
        n_poses=args.poses,
        n_configurations=args.configurations,
        model=model,
        q3=args.q3,
    )
    table = plan.table.copy()
    for j in range(chain.n_joints):
        table[f"q{j + 1}_deg"] = np.degrees(table[f"q{j + 1}"])
    write_csv(args.out, table)
    print(
        f"{args.out}: {len(table)} configurations of {table['pose'].nunique()} poses from "
        f"{plan.candidates} candidate poses; discarded: {plan.discarded}"
    )


def _plan_chain(args: argparse.Namespace):
    if args.urdf is None:
        raise InputError("needs the robot: --urdf (or --from-results, whose campaign names it)", key="--urdf")
    robot = {"urdf": args.urdf, "base": args.base, "flange": args.flange}
    return load_chain({k: v for k, v in robot.items() if v is not None}, Path.cwd(), Path.cwd(), source="command line")


def _candidate_count(args: argparse.Namespace) -> int | None:
    """--candidates as a number of poses (None when it names a file)."""
    try:
        value = int(args.candidates)
    except ValueError:
        return None
    if value < 1:
        raise InputError(f"must be at least 1 or a CSV file, got {value}", key="--candidates")
    return value


def _design_priors(args: argparse.Namespace, campaign=None):
    """The priors of the config's `priors` section (the library's defaults without a config file),
    with a campaign's own `robot.priors` over them."""
    config = read_yaml(args.config) if Path(args.config).is_file() else {}
    robot = None if campaign is None else campaign.robot
    source = "campaign.yaml" if campaign is None else f"{campaign.name}/campaign.yaml"
    return priors.priors_from(priors.with_defaults((config or {}).get("priors")), robot, source)


def _plan_workspace(args: argparse.Namespace) -> None:
    """`remaster plan --objective workspace` and `--from-results`: the greedy design (analysis.design)."""
    if args.budget is None and args.target_mm is None:
        raise InputError("a workspace design needs --budget N, --target-mm X or both", key="--budget")
    rng = np.random.default_rng(args.seed)
    if args.from_results is not None:
        results = Path(args.from_results)
        campaign = read_campaign(args.campaign or Path("data") / "raw" / results.parent.name, Path.cwd())
        sensor = campaign.sensors.get(results.name)
        if sensor is None:
            raise InputError(
                f"names no sensor of campaign {campaign.name} ({', '.join(campaign.sensors)}): give "
                "results/<campaign>/<sensor>",
                file=str(results),
            )
        found = sensor_results(results, ("registration", "laplace", "loop"))
        loop = found["loop"]
        gross = loop.gross_errors.get("optimization", []) if loop.gross_errors else []
        exclude = sorted(set(found["laplace"].outlier_rows) | set(int(r) for r in gross))
        chain = campaign.chain
        measured_gp = loop.residual_gp if loop.residual_gp and loop.residual_gp.get("structure_found") else None
        # the parametric fit's sigma holds the discrepancy the GP found: with the GP as the robust
        # criterion's discrepancy, the noise is the GP's own, or the discrepancy would count twice
        robust_gp = measured_gp is not None and args.criterion == design_discrepancy.CRITERION
        sigma = float(measured_gp["hyperparameters"]["noise_std_m"]) if robust_gp else loop.sigma_after
        start = design_inputs.campaign_prior(
            chain, sensor, found["registration"].t_nr, sigma, _design_priors(args, campaign), exclude=exclude
        )
        model, information = start.model, start.information
        measured = sensor.table.loc[start.rows, list(sensor.joint_columns)].to_numpy(dtype=float)
        marker = sensor.marker
        origin = _campaign_sensor_origin(args, chain, found["registration"].t_nr, sensor, measured)
        moved = ", ".join(f"q{j + 1} {f:.0%}" for j, f in enumerate(start.moved_fraction))
        print(f"{results}: {len(start.rows)} measured rows; share of each joint's range moved: {moved}")
    else:
        chain = _plan_chain(args)
        origin = _sensor_origin(args, chain)
        marker = np.asarray(args.marker, dtype=float)
        t_nr = np.eye(4)
        t_nr[:3, 3] = -origin  # the sensor's orientation does not change a position bound's size
        if not args.noise_mm > 0:
            raise InputError(f"must be > 0 mm, got {args.noise_mm}", key="--noise-mm")
        model = design_posterior.complete_error_model(chain, marker, t_nr, _design_priors(args), args.noise_mm * 1e-3)
        information = model.prior_information()
        measured, measured_gp = np.zeros((0, chain.n_joints)), None
    count = _candidate_count(args)
    if count is None:
        candidates = design_inputs.table_candidates(read_csv(args.candidates), chain, str(args.candidates))
    else:
        collision = planning.CollisionModel(link_radius=args.link_radius, floor_height=args.floor)
        candidates = design_inputs.generated_candidates(
            chain, origin, marker, rng, poses=count, collision=collision, set_name=args.set
        )
    q = design_inputs.configurations(candidates, chain.n_joints)
    within = q if args.workspace == "candidates" else None
    evaluation = design.evaluation_configurations(chain, args.evaluation, rng, within=within)
    target = None if args.target_mm is None else args.target_mm * 1e-3
    if args.criterion == design_discrepancy.CRITERION:
        if len(measured) > design_discrepancy.MAX_MEASURED_ROWS:
            raise InputError(
                f"the campaign has {len(measured)} measured rows; the robust criterion takes at most "
                f"{design_discrepancy.MAX_MEASURED_ROWS} (their discrepancy kernel grows as the rows squared): "
                "use --criterion workspace",
                key="--criterion",
            )
        discrepancy = _discrepancy(args, evaluation, model.sigma, measured_gp)
        print(f"discrepancy prior: {discrepancy.report()}")
        chosen = design_discrepancy.robust_design(
            model.whitened_jacobian(q),
            q,
            model.jacobian(evaluation),
            evaluation,
            information,
            discrepancy,
            model.sigma,
            budget=args.budget,
            target=target,
            measured_jacobian=model.whitened_jacobian(measured),
            q_measured=measured,
        )
    else:
        chosen = design.greedy_design(
            model.whitened_jacobian(q),
            model.jacobian(evaluation),
            information,
            budget=args.budget,
            target=target,
            criterion=args.criterion,
            statistic=args.statistic,
        )
    if args.exchange:
        chosen = design.exchange_design(chosen, model.whitened_jacobian(q), model.jacobian(evaluation), information)
    out = Path(args.out)
    stem = out.with_name(out.stem + "_bound")
    write_csv(out, design.chosen_table(candidates, chosen, chain.n_joints))
    bounds = design.bound_table(chosen)
    write_csv(stem.with_suffix(".csv"), bounds)
    write_figure(
        stem,
        figures_design.bound_curve(bounds, f"{len(chosen.chosen)} configurations ({args.criterion})", args.target_mm),
    )
    what = (
        f"expected RMS error per axis across the workspace, with the discrepancy, {chosen.final_bound_mm:.4g} mm"
        if chosen.statistic == "rms"
        else f"predicted workspace 95 % bound {chosen.final_bound_mm:.4g} mm ({args.statistic})"
    )
    print(
        f"{out}: {len(chosen.chosen)} of {len(candidates)} candidate configurations ({args.criterion}; stopped: "
        f"{chosen.stopped}); {what}; against n in {stem.with_suffix('.csv')}"
    )


def _campaign_sensor_origin(args: argparse.Namespace, chain, t_nr, sensor, measured) -> np.ndarray:
    """Where a calibrated campaign's sensor stands in the robot base frame (m), for the sight lines of
    generated candidates: --sensor-origin when given, else the registration's. A campaign whose
    coordinates were moved to the robot's frame before it was published registers to about the
    identity, which puts the sensor at the robot's base: if none of its own measured rows would be
    seen from there, the registration does not say where the sensor was, and a generated design would
    be checked against the wrong sight line."""
    if args.sensor_origin is not None:
        return np.asarray(args.sensor_origin, dtype=float)
    origin = np.linalg.inv(t_nr)[:3, 3]
    if _candidate_count(args) is None or not len(measured):
        return origin  # candidates given: no sight line is checked
    collision = planning.CollisionModel(link_radius=args.link_radius, floor_height=args.floor)
    seen = planning.marker_visible(chain, measured, planning.SightLine(origin, sensor.marker), collision)
    if not seen.any():
        raise InputError(
            f"the registration puts the sensor at ({origin[0]:.3f}, {origin[1]:.3f}, {origin[2]:.3f}) m in the "
            f"robot frame, from where none of the campaign's {len(measured)} measured rows would be seen: its "
            "coordinates are not the sensor's own (moved to the robot's frame?); give the sensor's position "
            "--sensor-origin X Y Z (m, robot base frame), or the candidates --candidates FILE",
            key="--sensor-origin",
        )
    return origin


def _discrepancy(args: argparse.Namespace, evaluation, sigma: float, measured_gp: dict | None):
    """The robust criterion's discrepancy prior: a campaign's residual GP when its loop found structure
    (--from-results; a joint it never turned takes its workspace range), else the default (the
    sensor's noise as signal, each joint's workspace range as lengthscale); --discrepancy-mm sets the
    signal std of either."""
    if args.discrepancy_mm is not None and not args.discrepancy_mm >= 0:
        raise InputError(f"must be >= 0 mm, got {args.discrepancy_mm}", key="--discrepancy-mm")
    if measured_gp is not None:
        found = design_discrepancy.discrepancy_of(measured_gp["hyperparameters"], evaluation)
        signal = found.signal_std if args.discrepancy_mm is None else args.discrepancy_mm * 1e-3
        return design_discrepancy.Discrepancy(found.lengthscales, signal)
    signal = sigma if args.discrepancy_mm is None else args.discrepancy_mm * 1e-3
    return design_discrepancy.workspace_discrepancy(evaluation, signal)


def _import(args: argparse.Namespace) -> None:
    folder, report = import_campaign(args.config, args.raw_dir, Path.cwd(), overwrite=args.force)
    total = report["controller"]["rows"]
    rows = {name: f"{s['matched']} of {total} rows matched" for name, s in report["sensors"].items()}
    print(
        f"{args.config}: wrote {folder} ({rows}); {report['unmatched_rows']} unmatched sensor rows listed in "
        f"{folder / importer.REPORT_FILE}"
    )


def _program(args: argparse.Namespace) -> None:
    robot = {"urdf": args.urdf, "base": args.base, "flange": args.flange}
    chain = load_chain({k: v for k, v in robot.items() if v is not None}, Path.cwd(), Path.cwd(), source="command line")
    given = programs.configurations(read_csv(args.configurations), chain, args.configurations, args.urdf)
    out = Path(args.out)
    table_path = Path(args.table) if args.table else out.with_suffix(".csv")
    if table_path.resolve() == out.resolve():
        raise InputError("the program and its configurations table would be the same file: give --table", key="--out")
    for option, path in (("--out", out), ("--table", table_path)):
        if path.resolve() == Path(args.configurations).resolve():
            raise InputError(
                f"would overwrite the configurations {args.configurations}: give another {option}", key=option
            )
    speed, acceleration = programs.DEFAULT_MOTION[args.format]
    settings = programs.Settings(
        speed=speed if args.speed is None else args.speed,
        acceleration=acceleration if args.acceleration is None else args.acceleration,
        dwell=args.dwell,
        name=out.stem if args.format == "krl" else "remaster_campaign",
    )
    tour = joint_tour.joint_tour(given.q, args.order)
    as_given = joint_tour.joint_tour(given.q, "as-given")
    ordered = given.take(tour.order)
    text = programs.program_text(
        ordered,
        args.format,
        settings,
        header=[f"remaster program from {args.configurations} ({args.urdf}), order {args.order}"],
    )
    if args.check:
        worst = programs.check_program(text, args.format, ordered, str(out))
        print(f"{out}: reads back as the {len(ordered.q)} configurations in order, to {np.degrees(worst):.2g} deg")
    write_text(out, text)
    write_csv(table_path, programs.controller_table(ordered, args.format))
    print(
        f"{out}: {len(ordered.q)} configurations ({args.format}, order {args.order}): joint travel "
        f"{np.degrees(tour.total):.1f} deg in all (the largest joint motion of each move, summed), largest move "
        f"{np.degrees(tour.largest):.1f} deg; as given {np.degrees(as_given.total):.1f} and "
        f"{np.degrees(as_given.largest):.1f} deg. {table_path}: the same configurations for `remaster import` "
        "(key column point, joints q1..qN in rad). Check the program on the robot's simulator before running it."
    )


def _calibrated(args: argparse.Namespace) -> tuple[object, compensation.CalibratedRobot]:
    campaign = read_campaign(args.campaign, Path.cwd())
    results = sensor_results(sensor_folder(args.results, Path(args.campaign).name, args.sensor))
    label = str(Path(args.results) / Path(args.campaign).name / args.sensor)
    robot = compensation.calibrated_robot(campaign, args.sensor, args.model, results, args.tcp, label)
    for note in robot.notes(args.frame):
        print(f"note: {note}", file=sys.stderr)
    return campaign, robot


def _predict(args: argparse.Namespace) -> None:
    _, robot = _calibrated(args)
    q = compensation.joint_commands(read_csv(args.commands), robot.chain, args.commands)
    table = compensation.predict(robot, q, args.frame, args.draws, np.random.default_rng(args.seed))
    write_csv(args.out, table)
    print(
        f"{args.out}: {len(table)} predicted positions ({args.model} model, {args.frame} frame); largest "
        f"95 % bound {table['bound95_mm'].max():.4g} mm"
    )


def _compensate(args: argparse.Namespace) -> int:
    campaign, robot = _calibrated(args)
    targets, q = compensation.targets_or_commands(read_csv(args.targets), robot.chain, args.targets)
    rng = np.random.default_rng(args.seed)
    if targets is not None:
        out = compensation.compensate(
            robot,
            args.frame,
            args.draws,
            rng,
            targets=targets,
            seeds=q,
            candidates=campaign.sensors[args.sensor].q("optimization"),
        )
    else:
        out = compensation.compensate(robot, args.frame, args.draws, rng, commands=q)
    write_csv(args.out, out)
    reached = out["status"] == compensation.REACHED
    print(
        f"{args.out}: {int(reached.sum())} of {len(out)} targets reached ({args.model} model, {args.frame} frame); "
        f"largest 95 % bound {out['bound95_mm'].max():.4g} mm"
    )
    left = compensation.not_reached_summary(out)
    if left:
        print(f"remaster compensate: {left}", file=sys.stderr)
        return NOT_REACHED_STATUS
    return 0


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _calibration_arguments(command: argparse.ArgumentParser) -> None:
    command.add_argument("--campaign", required=True, metavar="FOLDER", help="the campaign folder (data/raw/<name>)")
    command.add_argument("--sensor", required=True, help="the sensor whose calibration to use")
    command.add_argument(
        "--results",
        default="results",
        metavar="FOLDER",
        help="the results folder `snakemake -j2` wrote (its results_dir)",
    )
    command.add_argument(
        "--model",
        default="loop",
        choices=compensation.MODELS,
        help="the paper's model (zero-offsets) or the loop-closed model (default)",
    )
    command.add_argument(
        "--frame",
        default="robot",
        choices=compensation.FRAMES,
        help="positions in the robot's base frame, or in the sensor's frame of this campaign's set-up",
    )
    command.add_argument(
        "--tcp",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="a tool centre point in the flange frame (m); default: the sensor's marker",
    )
    command.add_argument("--draws", type=_positive, default=2000, help="posterior draws for the 95 %% bounds")
    command.add_argument("--seed", type=int, default=0, help="seed of the posterior draws")


def parser() -> argparse.ArgumentParser:
    main = argparse.ArgumentParser(prog="remaster", description=" ".join(__doc__.split("\n\n")[0].split()))
    commands = main.add_subparsers(dest="command", required=True)

    simulate = commands.add_parser("simulate", help="regenerate simulated campaigns from scenarios")
    simulate.add_argument("scenarios", nargs="*", help=f"scenario YAML files (default: {DEFAULT_SCENARIOS}/*.yaml)")
    simulate.add_argument("--raw-dir", default="data/raw", help="where campaign folders go")
    simulate.add_argument("--truth-dir", default="data/truth", help="where ground-truth JSON goes")
    simulate.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    simulate.add_argument(
        "--copies",
        type=int,
        default=None,
        metavar="N",
        help="a fleet: N campaigns <name>-001 ... from seeds seed, seed + 1, ... (new poses and noise)",
    )
    simulate.set_defaults(run=_simulate)

    plan = commands.add_parser("plan", help="joint configurations to command for a measurement campaign")
    plan.add_argument("--urdf", help="robot URDF (not with --from-results: the campaign's)")
    plan.add_argument("--base", help="base frame (default: the URDF root)")
    plan.add_argument("--flange", help="flange frame (default: the URDF's single leaf)")
    where = plan.add_mutually_exclusive_group()
    where.add_argument(
        "--sensor-origin",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="reference sensor origin in the robot base frame (m)",
    )
    where.add_argument(
        "--registration-points",
        metavar="CSV",
        help="three configurations q1..qN (rad) with the marker measured by the sensor x, y, z (m): "
        "the sensor origin comes from a three-point registration as in the paper",
    )
    plan.add_argument(
        "--marker",
        nargs=3,
        type=float,
        default=[0.0, 0.0, 0.0],
        metavar=("X", "Y", "Z"),
        help="marker in the flange frame (m)",
    )
    plan.add_argument("--set", default="optimization", choices=["optimization", "validation"])
    plan.add_argument(
        "--candidates",
        default="60",
        metavar="N|CSV",
        help="Latin-hypercube poses per batch; with --objective workspace: the candidate poses (every joint "
        "free), or a CSV of candidate configurations q1..qN (rad), e.g. a plan or a campaign's rows",
    )
    plan.add_argument("--poses", type=int, help="exact number of poses (needs --configurations)")
    plan.add_argument("--configurations", type=int, help="exact number of configurations (needs --poses)")
    plan.add_argument(
        "--q3", type=float, default=0.0, help="joint 3 held at this angle (rad) by the inverse kinematics"
    )
    plan.add_argument("--link-radius", type=float, default=0.06, help="capsule radius of the links (m)")
    plan.add_argument("--floor", type=float, default=0.0, help="floor height in the base frame (m)")
    plan.add_argument(
        "--objective",
        default="paper",
        choices=["paper", "workspace"],
        help="paper: the paper's planner (joint 3 held); workspace: the configurations that most reduce the "
        "calibrated model's predicted 95 %% bound across the workspace, chosen greedily (docs/planning.md)",
    )
    plan.add_argument("--budget", type=_positive, help="workspace: at most N configurations")
    plan.add_argument(
        "--target-mm",
        type=float,
        help="workspace: stop once the predicted bound (robust: the expected RMS error per axis) is at or below X mm",
    )
    plan.add_argument(
        "--criterion",
        default="workspace",
        choices=[*design.CRITERIA, design_discrepancy.CRITERION],
        help="workspace: the bound across the workspace; d-optimal: log det of the information; robust: the "
        "expected error across the workspace with a discrepancy the error model lacks (docs/planning.md)",
    )
    plan.add_argument(
        "--discrepancy-mm",
        type=float,
        help="robust: the discrepancy's std per axis (mm; default: the sensor's noise, or the residual GP's "
        "of --from-results when its loop found structure)",
    )
    plan.add_argument(
        "--exchange",
        action="store_true",
        help="workspace: after the greedy choice, swap chosen configurations for candidates while the bound falls "
        "(the number stays; the curve is then the exchanged set's, in its order)",
    )
    plan.add_argument(
        "--statistic",
        default="p95",
        choices=list(design.STATISTICS),
        help="workspace: the 95th percentile or the mean over the workspace of the per-configuration bound",
    )
    plan.add_argument(
        "--evaluation",
        type=_positive,
        default=design.EVALUATION_CONFIGURATIONS,
        help="workspace: configurations uniform across the joint limits the bound is taken at",
    )
    plan.add_argument(
        "--workspace",
        default="limits",
        choices=["limits", "candidates"],
        help="workspace: where the bound is taken: across the joint limits, or within the candidates' joint "
        "ranges (a robot that works in one region)",
    )
    plan.add_argument("--noise-mm", type=float, default=0.01, help="workspace: the sensor's noise per axis (mm)")
    plan.add_argument(
        "--config", default="config.yaml", help="workspace: the config whose priors the error model takes"
    )
    plan.add_argument(
        "--from-results",
        metavar="FOLDER",
        help="the next configurations of a calibrated campaign: its results folder <results_dir>/<campaign>/"
        "<sensor>; its measured rows and fitted noise are the prior",
    )
    plan.add_argument(
        "--campaign", metavar="FOLDER", help="with --from-results: the campaign folder (default data/raw/<campaign>)"
    )
    plan.add_argument("--seed", type=int, default=0)
    plan.add_argument("--out", default="plan.csv")
    plan.set_defaults(run=_plan)

    imp = commands.add_parser("import", help="build a campaign folder from a controller log and sensor CSV exports")
    imp.add_argument(
        "--config",
        required=True,
        metavar="IMPORT.yaml",
        help="campaign metadata, the controller log and sensor files with their columns, units and "
        "matching (format: remaster.campaigns.importer)",
    )
    imp.add_argument("--raw-dir", default="data/raw", help="where the campaign folder goes")
    imp.add_argument("--force", action="store_true", help="replace an existing campaign folder's files")
    imp.set_defaults(run=_import)

    program = commands.add_parser(
        "program", help="a robot program (URScript, KRL, RAPID) that visits planned configurations"
    )
    program.add_argument("--urdf", required=True, help="robot URDF (its joint limits are checked)")
    program.add_argument("--base", help="base frame (default: the URDF root)")
    program.add_argument("--flange", help="flange frame (default: the URDF's single leaf)")
    program.add_argument(
        "--configurations",
        required=True,
        metavar="CSV",
        help="configurations q1..qN (rad), with set, pose, solution: what `remaster plan` writes",
    )
    program.add_argument("--format", required=True, choices=programs.FORMATS)
    program.add_argument("--out", required=True, help="the program (a KRL program's DEF is named as this file)")
    program.add_argument(
        "--table",
        metavar="CSV",
        help="the configurations in the program's order, for `remaster import` (default: --out with suffix .csv)",
    )
    program.add_argument(
        "--order",
        default="tour",
        choices=("tour", "as-given"),
        help="tour: nearest neighbour then 2-opt on the largest joint motion of each move; as-given: the CSV's order",
    )
    program.add_argument(
        "--speed",
        type=float,
        help="urscript: joint speed (rad/s, default {urscript[0]:g}); krl: %% of each axis's maximum ($VEL_AXIS, "
        "default {krl[0]:g}); rapid: VelSet override %% (default {rapid[0]:g})".format(**programs.DEFAULT_MOTION),
    )
    program.add_argument(
        "--acceleration",
        type=float,
        help="urscript: joint acceleration (rad/s^2, default {urscript[1]:g}); krl: %% ($ACC_AXIS, default "
        "{krl[1]:g}); rapid: AccSet %% (default {rapid[1]:g})".format(**programs.DEFAULT_MOTION),
    )
    program.add_argument(
        "--dwell", type=float, default=programs.DEFAULT_DWELL, help="wait at each configuration for the measurement (s)"
    )
    program.add_argument(
        "--check",
        action="store_true",
        help="read the program back and compare it with the configurations before writing",
    )
    program.set_defaults(run=_program)

    predict = commands.add_parser("predict", help="where the calibrated robot puts the marker or TCP at joint commands")
    _calibration_arguments(predict)
    predict.add_argument("--commands", required=True, metavar="CSV", help="joint commands q1..qN (rad), one per row")
    predict.add_argument("--out", default="predicted.csv")
    predict.set_defaults(run=_predict)

    compensate = commands.add_parser("compensate", help="joint commands that reach targets under the calibrated model")
    _calibration_arguments(compensate)
    compensate.add_argument(
        "--targets",
        required=True,
        metavar="CSV",
        help="target positions x, y, z (m, in --frame), optionally with seed commands q1..qN "
        "(rad); or nominal joint commands q1..qN alone",
    )
    compensate.add_argument("--out", default="compensated.csv")
    compensate.set_defaults(run=_compensate)
    return main


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if getattr(args, "poses", None) is not None and getattr(args, "configurations", None) is None:
        parser().error("--poses needs --configurations")
    try:
        status = args.run(args)
    except RemasterError as exc:
        print(f"remaster {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return status or 0


if __name__ == "__main__":
    sys.exit(main())
