"""Command line: `remaster plan`, `remaster program`, `remaster simulate`, `remaster import`,
`remaster predict` and `remaster compensate`.

Each subcommand reads its inputs, calls the library and writes its outputs; errors in the input
end with a message naming the file, key or column and rows, and exit status 2 (nothing written).
`remaster compensate` exits with status 3 when it wrote its table but some targets were not
reached (each such row says why).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import sys
import time
from dataclasses import fields
from importlib.metadata import version
from pathlib import Path

import numpy as np

from . import DISTRIBUTION
from .calibration import compensation
from .campaigns import importer, scenario
from .campaigns.campaign import check_folder_name
from .campaigns.folders import import_campaign, read_campaign, write_campaign
from .campaigns.robot_model import load_chain
from .errors import InputError, RemasterError
from .files import read_csv, read_yaml, write_csv, write_figure, write_json, write_text
from .planning import design, plan, programs, robust_design
from .results import check_made_from, sensor_folder, sensor_results
from .robot import priors

DEFAULT_SCENARIOS = Path("data") / "simulation"
NOT_REACHED_STATUS = 3


PROGRESS_EVERY = 2.0  # s: on a terminal, a long command says what it is doing at most this often


class _Progress(logging.Handler):
    """What the library logs (INFO and above), as `remaster <command>: <message>` on a terminal's
    standard error, at most every PROGRESS_EVERY seconds (the first at once; warnings always)."""

    def __init__(self, command: str):
        super().__init__(logging.INFO)
        self.command, self.last = command, -math.inf

    def emit(self, record: logging.LogRecord) -> None:
        now = time.monotonic()
        if record.levelno > logging.INFO or now - self.last >= PROGRESS_EVERY:
            self.last = now
            print(f"remaster {self.command}: {record.getMessage()}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def _progress(command: str):
    """While a command runs, its progress on standard error when that is a terminal; nothing
    when it is piped or logged, which then get only the results and the errors."""
    if not sys.stderr.isatty():
        yield
        return
    logger, handler = logging.getLogger("remaster"), _Progress(command)
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def _simulate(args: argparse.Namespace) -> None:
    paths = [Path(p) for p in args.scenarios] or sorted(DEFAULT_SCENARIOS.glob("*.yaml"))
    if not paths:
        raise RemasterError(f"no scenario given and none found in {DEFAULT_SCENARIOS}")
    for path in paths:
        base = read_yaml(path)
        check_folder_name(base.get("name") if isinstance(base, dict) else None, str(path))
        chain = load_chain(base["robot"], path.parent, Path.cwd(), source=str(path), name=base["name"])
        for spec, seed in scenario.copies(base, args.copies, args.seed):
            campaign = scenario.simulate(spec, chain, seed=seed)
            folder = write_campaign(Path(args.raw_dir) / spec["name"], campaign.metadata, campaign.tables)
            truth = write_json(Path(args.truth_dir) / f"{spec['name']}.json", campaign.truth)
            rows = {name: len(t) for name, t in campaign.tables.items()}
            print(f"{path}: wrote {folder} ({rows}) and {truth}")


def _plan_options(args: argparse.Namespace) -> plan.PlanOptions:
    names = [f.name for f in fields(plan.PlanOptions)]
    vectors = ("marker", "sensor_origin", "cube_centre")
    given = {name: getattr(args, name) for name in names if name not in ("from_results", *vectors)}
    return plan.PlanOptions(
        **given,
        **{name: None if getattr(args, name) is None else tuple(getattr(args, name)) for name in vectors},
        from_results=args.from_results is not None,
    )


def _sensor_origin(args: argparse.Namespace, chain) -> np.ndarray:
    if args.sensor_origin is not None:
        return np.asarray(args.sensor_origin, dtype=float)
    if args.registration_points is None:
        raise InputError("needs the sensor: --sensor-origin X Y Z or --registration-points CSV", key="--sensor-origin")
    points = read_csv(args.registration_points)
    return plan.sensor_origin_from_points(chain, points, args.marker, str(args.registration_points))


def _plan(args: argparse.Namespace) -> None:
    options = _plan_options(args)
    plan.check_options(options)
    if options.workspace_design:
        _plan_workspace(args, options)
        return
    chain = _plan_chain(args)
    origin = _sensor_origin(args, chain)
    if options.objective == plan.ISO9283:
        planned = plan.iso9283_plan(chain, origin, options)
    else:
        planned = plan.paper_plan(chain, origin, options, np.random.default_rng(args.seed))
    write_csv(args.out, planned.table)
    print(f"{args.out}: {planned.summary}")


def _plan_chain(args: argparse.Namespace):
    if args.urdf is None:
        raise InputError("needs the robot: --urdf (or --from-results, whose campaign names it)", key="--urdf")
    robot = {"urdf": args.urdf, "base": args.base, "flange": args.flange}
    return load_chain({k: v for k, v in robot.items() if v is not None}, Path.cwd(), Path.cwd(), source="command line")


def _design_priors(args: argparse.Namespace, campaign=None):
    """The priors of the config's `priors` section (the library's defaults without a config file),
    with a campaign's own `robot.priors` over them."""
    config = read_yaml(args.config) if Path(args.config).is_file() else {}
    robot = None if campaign is None else campaign.robot
    source = "campaign.yaml" if campaign is None else f"{campaign.name}/campaign.yaml"
    return priors.priors_from(priors.with_defaults((config or {}).get("priors")), robot, source)


def _plan_workspace(args: argparse.Namespace, options: plan.PlanOptions) -> None:
    """`remaster plan --objective workspace` and `--from-results` (`planning.plan.workspace_plan`)."""
    rng = np.random.default_rng(args.seed)
    if args.from_results is not None:
        results = Path(args.from_results)
        folder = args.campaign or Path("data") / "raw" / results.parent.name
        campaign = read_campaign(folder, Path.cwd())
        sensor = campaign.sensors.get(results.name)
        if sensor is None:
            raise InputError(
                f"names no sensor of campaign {campaign.name} ({', '.join(campaign.sensors)}): give "
                "results/<campaign>/<sensor>",
                file=str(results),
            )
        found = sensor_results(results, ("registration", "laplace", "loop"))
        check_made_from(results.parent.parent, folder, Path.cwd())  # results_dir/<campaign>/<sensor>
        start = plan.campaign_start(campaign, sensor, found, options, _design_priors(args, campaign))
        print(f"{results}: {start.note}")
    else:
        chain = _plan_chain(args)
        start = plan.nominal_start(chain, _sensor_origin(args, chain), options, _design_priors(args))
    table = None if options.candidate_count() is not None else read_csv(args.candidates)
    planned = plan.workspace_plan(start, options, rng, table, str(args.candidates))
    for note in planned.notes:
        print(note)
    out = Path(args.out)
    stem = out.with_name(out.stem + "_bound")
    write_csv(out, planned.chosen)
    write_csv(stem.with_suffix(".csv"), planned.bounds)
    write_figure(stem, planned.figure)
    print(f"{out}: {planned.summary}; against n in {stem.with_suffix('.csv')}")


def _import(args: argparse.Namespace) -> None:
    folder, report = import_campaign(args.config, args.raw_dir, Path.cwd(), overwrite=args.force)
    total = report["controller"]["rows"]
    rows = {  # a sensor topic's samples drive its rows: how many found a joint state
        name: f"{s['matched']} of {s['rows']} samples paired with a joint state"
        if "topic" in s
        else f"{s['matched']} of {total} rows matched"
        for name, s in report["sensors"].items()
    }
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
    header = [f"remaster program from {args.configurations} ({args.urdf}), order {args.order}"]
    program = programs.robot_program(given, args.format, settings, args.order, header, args.check, str(out))
    if program.checked:
        print(f"{out}: {program.checked}")
    write_text(out, program.text)
    write_csv(table_path, program.table)
    print(
        f"{out}: {program.summary}. {table_path}: the same configurations for `remaster import` "
        "(key column point, joints q1..qN in rad). Check the program on the robot's simulator before running it."
    )


def _calibrated(args: argparse.Namespace) -> tuple[object, compensation.CalibratedRobot]:
    campaign = read_campaign(args.campaign, Path.cwd())
    results = sensor_results(sensor_folder(args.results, Path(args.campaign).name, args.sensor))
    check_made_from(args.results, args.campaign, Path.cwd())
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
        f"95 % bound {table['bound95_mm'].max():.4g} mm{compensation.near_summary(table)}"
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
        f"largest 95 % bound {out['bound95_mm'].max():.4g} mm{compensation.near_summary(out)}"
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


def _simulate_command(commands) -> None:
    simulate = commands.add_parser("simulate", help="regenerate simulated campaigns from scenarios")
    simulate.add_argument("scenarios", nargs="*", help=f"scenario YAML files (default: {DEFAULT_SCENARIOS}/*.yaml)")
    simulate.add_argument("--raw-dir", default="data/raw", help="where campaign folders go")
    simulate.add_argument("--truth-dir", default="data/truth", help="where ground-truth JSON goes")
    simulate.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    simulate.add_argument(
        "--copies",
        type=_positive,
        default=None,
        metavar="N",
        help="a fleet: N campaigns <name>-001 ... from seeds seed, seed + 1, ... (new poses and noise)",
    )
    simulate.set_defaults(run=_simulate)


def _workspace_design_arguments(plan: argparse.ArgumentParser) -> None:
    """`remaster plan`'s options of the workspace design (docs/planning.md)."""
    plan.add_argument(
        "--objective",
        default="paper",
        choices=["paper", "workspace", "iso9283"],
        help="paper: the paper's planner (joint 3 held); workspace: the configurations that most reduce the "
        "calibrated model's predicted 95 %% bound across the workspace, chosen greedily (docs/planning.md); "
        "iso9283: the ISO 9283 pose test, P1..P5 of --cube-centre/--cube-edge for --cycles cycles",
    )
    plan.add_argument(
        "--cube-centre", nargs=3, type=float, metavar=("X", "Y", "Z"), help="iso9283: the cube's centre (m, base frame)"
    )
    plan.add_argument("--cube-edge", type=float, metavar="E", help="iso9283: the cube's edge (m)")
    plan.add_argument("--cycles", type=_positive, default=30, help="iso9283: cycles through P1..P5 (the standard: 30)")
    plan.add_argument("--budget", type=_positive, help="workspace: at most N configurations")
    plan.add_argument(
        "--target-mm",
        type=float,
        help="workspace: stop once the predicted bound (robust: the expected RMS error per axis) is at or below X mm",
    )
    plan.add_argument(
        "--criterion",
        default="workspace",
        choices=[*design.CRITERIA, robust_design.CRITERION],
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


def _plan_command(commands) -> None:
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
    _workspace_design_arguments(plan)
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


def _import_command(commands) -> None:
    imp = commands.add_parser(
        "import", help="build a campaign folder from a controller log (CSV or a ROS 2 MCAP bag) and sensor CSV exports"
    )
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


def _program_command(commands) -> None:
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


def _predict_command(commands) -> None:
    predict = commands.add_parser("predict", help="where the calibrated robot puts the marker or TCP at joint commands")
    _calibration_arguments(predict)
    predict.add_argument("--commands", required=True, metavar="CSV", help="joint commands q1..qN (rad), one per row")
    predict.add_argument("--out", default="predicted.csv")
    predict.set_defaults(run=_predict)


def _compensate_command(commands) -> None:
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


def parser() -> argparse.ArgumentParser:
    main = argparse.ArgumentParser(prog="remaster", description=" ".join(__doc__.split("\n\n")[0].split()))
    main.add_argument("--version", action="version", version=f"%(prog)s {version(DISTRIBUTION)}")
    commands = main.add_subparsers(dest="command", required=True)
    _simulate_command(commands)
    _plan_command(commands)
    _import_command(commands)
    _program_command(commands)
    _predict_command(commands)
    _compensate_command(commands)
    return main


# the options that name a file a command writes
OUTPUT_OPTIONS = ("out", "table")


def _refuse_directories(args: argparse.Namespace) -> None:
    """An output option naming a directory is refused before anything is computed or written (its
    write would fail only after the others' files were written)."""
    for name in OUTPUT_OPTIONS:
        value = getattr(args, name, None)
        if value is not None and Path(value).is_dir():
            raise InputError(f"{value} is a directory: give a file name", key=f"--{name}")


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if getattr(args, "poses", None) is not None and getattr(args, "configurations", None) is None:
        parser().error("--poses needs --configurations")
    try:
        _refuse_directories(args)
        with _progress(args.command):
            status = args.run(args)
    except RemasterError as exc:
        print(f"remaster {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return status or 0


if __name__ == "__main__":
    sys.exit(main())
