"""Robot programs that visit a campaign's configurations: URScript, KUKA KRL and ABB RAPID.

Input: a configurations table as `remaster plan` writes it (columns set, pose, solution, q1..qN
in rad, and optionally q1_deg..qN_deg; only q1..qN are required), checked against the robot's
joint limits (`configurations`). Output (`write_program`): the program text, one synchronised
joint move per configuration, each followed by a dwell for the measurement, and the table of the
configurations in the program's order that `remaster import` reads as its controller log
(`controller_table`). Every move is preceded by a comment `point <k>: plan row <r> (<set> pose
<p> solution <s>)`, k counted from 1 in the program's order and r the 0-based row of the given
table, so a measurement (a tracker's k-th point) is tied to its configuration.

The formats, and how their joints are written:

- urscript: `def remaster_campaign():` ... `end`, `movej([q1, ..., q6], a=<rad/s^2>, v=<rad/s>)`
  then `sleep(<s>)`; joints in rad, `RAD_DECIMALS` decimals.
- krl: a KUKA .src `DEF <name>()` ... `END`, axis speed and acceleration in % of each axis's
  maximum ($VEL_AXIS, $ACC_AXIS), `PTP {A1 .., ..., A6 ..}` then `WAIT SEC <s>`; joints in deg,
  `DEG_DECIMALS` decimals. A 7-axis arm's redundant joint (the third from the base, as on KUKA's
  LBR 4+, the LWR IV+, under a KR C controller) is the external axis E1: q1, q2 -> A1, A2; q3 -> E1; q4..q7 ->
  A3..A6. No .dat is needed: the module declares nothing. Every KRL program written is checked
  against `krl_grammar`, a strict grammar of this subset, before it is returned.
- rapid: `MODULE <name>` ... `PROC main()` ... `ENDPROC` ... `ENDMODULE`, `VelSet`/`AccSet` in %,
  `MoveAbsJ [[j1..j6],[eax_a..eax_f]]\\NoEOffs, v1000, fine, tool0;` then `WaitTime \\InPos, <s>;`;
  joints in deg, `DEG_DECIMALS` decimals, 9E9 for an axis not used. A 7-axis arm's third joint
  is eax_a, as on ABB's YuMi (IRB 14000), whose arm-angle joint is programmed that way.

The values printed are the commands: the controller table holds them (converted back to rad),
not the unrounded plan, so table and program agree exactly. The joint angles are the URDF's; the
URDF must share the controller's zero and sign of every joint. Nothing here checks collisions
beyond the planner's capsule model: a program is run first on the robot's simulator.

`parse_program` reads any of the three formats back to joint values (rad) in program order and
the plan rows of their comments. This module works on text and tables; the command line
(`remaster program`) reads and writes the files.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import InputError, quoted, require_columns
from ..robot.kinematics import KinematicChain
from .joint_tour import joint_tour
from .krl_grammar import check_krl

FORMATS = ("urscript", "krl", "rapid")
SETS = ("optimization", "validation")
RAD_DECIMALS = 6  # URScript joints in rad: 5e-7 rad rounding, 0.5 um at 1 m
DEG_DECIMALS = 4  # KRL and RAPID joints in deg (single-precision REAL / num): 5e-5 deg, 0.9 um at 1 m
EXTERNAL_JOINT = 2  # 0-based joint of a 7-axis arm written as the external axis (E1, eax_a)
RAPID_UNUSED = "9E9"
RAPID_MIN_ACCELERATION = 20.0  # %: AccSet treats anything lower as 20 % (RAPID reference, AccSet)
ANGLE_TOLERANCE = 1e-9  # rad: a configuration this close to a joint limit is within it


@dataclass(frozen=True)
class Configurations:
    """Checked configurations: q (n, N) rad; set (n,) str; pose, solution (n,) int; rows (n,) the
    0-based rows of the table they came from."""

    q: np.ndarray
    set: np.ndarray
    pose: np.ndarray
    solution: np.ndarray
    rows: np.ndarray

    def take(self, order) -> Configurations:
        """These configurations in `order` (n,)."""
        order = np.asarray(order, dtype=int)
        return Configurations(self.q[order], self.set[order], self.pose[order], self.solution[order], self.rows[order])


@dataclass(frozen=True)
class Settings:
    """How the program moves: speed and acceleration (urscript: rad/s and rad/s^2 of the leading
    joint; krl and rapid: % of the axes' maximum / of the programmed speed and acceleration),
    dwell (s) at each configuration for the measurement, and the program's name (a KRL DEF must
    be named as its file)."""

    speed: float
    acceleration: float
    dwell: float
    name: str = "remaster_campaign"


# Defaults of `remaster program` per format: (speed, acceleration). URScript's movej defaults are
# 1.05 rad/s and 1.4 rad/s^2; a campaign moves slower so the tracker can follow.
DEFAULT_MOTION = {"urscript": (0.5, 0.5), "krl": (20.0, 20.0), "rapid": (20.0, 20.0)}
DEFAULT_DWELL = 2.0  # s: the arm settles and the sensor measures


def _numbers(table: pd.DataFrame, column: str, source: str) -> np.ndarray:
    values = pd.to_numeric(table[column], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise InputError("not a finite number", file=source, key=column, rows=bad)
    return values


def _integers(table: pd.DataFrame, column: str, source: str) -> np.ndarray:
    values = _numbers(table, column, source)
    bad = np.flatnonzero((values < 0) | (values != np.round(values)))
    if bad.size:
        raise InputError("not a non-negative integer", file=source, key=column, rows=bad)
    return values.astype(np.int64)


def configurations(table: pd.DataFrame, chain: KinematicChain, source: str, urdf: str) -> Configurations:
    """Check a configurations table (as `remaster plan` writes it) against the chain and return it.

    Needs q1..qN (rad) for the chain's N joints, no further qK, finite numbers within the joint
    limits of the URDF (`urdf` names it in the error); set (optimization|validation), pose and
    solution are optional (default optimization, pose = row, solution 0) and must not repeat
    together, as `remaster import` asks. A qK_deg column, where given, must agree with qK to
    1e-6 deg (a hand edit of one but not the other). Errors name `source`, the column and the
    0-based rows."""
    if len(table) == 0:
        raise InputError("no configurations (no rows)", file=source)
    n = chain.n_joints
    names = [f"q{j + 1}" for j in range(n)]
    require_columns(table, names, file=source, kind="joint", note=f"the robot has {n} joints", listed=True)
    extra = sorted(
        (c for c in map(str, table.columns) if re.fullmatch(r"q\d+", c) and c not in names), key=lambda c: int(c[1:])
    )
    if extra:
        raise InputError(f"more joint columns than the robot's {n} joints ({urdf})", file=source, key=", ".join(extra))
    q = np.column_stack([_numbers(table, c, source) for c in names])
    for j, name in enumerate(names):
        if f"{name}_deg" in table.columns:
            degrees = _numbers(table, f"{name}_deg", source)
            off = np.flatnonzero(np.abs(degrees - np.degrees(q[:, j])) > 1e-6)
            if off.size:
                raise InputError(
                    f"disagrees with {name} (rad): edited one but not the other?",
                    file=source,
                    key=f"{name}_deg",
                    rows=off,
                )
        outside = np.flatnonzero(
            (q[:, j] < chain.lower[j] - ANGLE_TOLERANCE) | (q[:, j] > chain.upper[j] + ANGLE_TOLERANCE)
        )
        if outside.size:
            raise InputError(
                f"beyond the limits [{chain.lower[j]:.4g}, {chain.upper[j]:.4g}] rad of joint "
                f"{chain.joint_names[j]} in {urdf} (configurations are in rad)",
                file=source,
                key=name,
                rows=outside,
            )
    sets = (
        table["set"].astype(str).to_numpy(dtype=object)
        if "set" in table.columns
        else np.full(len(table), SETS[0], object)
    )
    unknown = np.flatnonzero([s not in SETS for s in sets])
    if unknown.size:
        raise InputError(f"unknown set (use {' or '.join(SETS)})", file=source, key="set", rows=unknown)
    pose = _integers(table, "pose", source) if "pose" in table.columns else np.arange(len(table), dtype=np.int64)
    solution = _integers(table, "solution", source) if "solution" in table.columns else np.zeros(len(table), np.int64)
    repeated = np.flatnonzero(pd.DataFrame({"s": sets, "p": pose, "k": solution}).duplicated(keep=False).to_numpy())
    if repeated.size:
        raise InputError(
            "repeated: each (set, pose, solution) may appear once",
            file=source,
            key="set, pose, solution",
            rows=repeated,
        )
    return Configurations(q, sets, pose, solution, np.arange(len(table), dtype=np.int64))


# --------------------------------------------------------------------------- writing


def _number(value: float, decimals: int) -> str:
    text = f"{value:.{decimals}f}"
    return text[1:] if re.fullmatch(r"-0\.?0*", text) else text  # no "-0.0000"


def printed(q, fmt: str) -> np.ndarray:
    """Joint values q (..., N) rad as the format prints them, back in rad: what the robot is commanded."""
    q = np.asarray(q, dtype=float)
    if fmt == "urscript":
        return np.round(q, RAD_DECIMALS)
    return np.radians(np.round(np.degrees(q), DEG_DECIMALS))


def _comment(point: int, c: Configurations, i: int) -> str:
    return f"point {point}: plan row {c.rows[i]} ({c.set[i]} pose {c.pose[i]} solution {c.solution[i]})"


def _check_settings(fmt: str, settings: Settings) -> None:
    for key in ("speed", "acceleration", "dwell"):
        value = getattr(settings, key)
        if not (np.isfinite(value) and (value > 0 or (key == "dwell" and value == 0))):
            raise InputError(f"must be a positive number, got {quoted(value)}", key=key)
        if key != "dwell" and fmt != "urscript" and value > 100:
            raise InputError(f"is a percentage for {fmt}: at most 100, got {quoted(value)}", key=key)
    if fmt == "rapid" and settings.acceleration < RAPID_MIN_ACCELERATION:
        raise InputError(
            f"RAPID's AccSet takes at least {RAPID_MIN_ACCELERATION:g} % (less acts as {RAPID_MIN_ACCELERATION:g} %), "
            f"got {settings.acceleration:g}",
            key="acceleration",
        )
    if fmt == "krl" and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]{0,23}", settings.name):
        raise InputError(
            f"a KRL program's DEF is named as its file: {settings.name!r} is not a KRL name "
            "(a letter or _, then letters, digits or _, at most 24 characters)",
            key="name",
        )


def _urscript(c: Configurations, s: Settings, header: list[str]) -> list[str]:
    # `def` in the first column of the first line: the controller's socket interfaces run a script
    # as a program only then, so the header is the program's first comments
    lines = [f"def {s.name}():"] + [f"  # {h}" for h in header]
    for point, i in enumerate(range(len(c.q)), start=1):
        joints = ", ".join(_number(v, RAD_DECIMALS) for v in c.q[i])
        lines += [
            f"  # {_comment(point, c, i)}",
            f"  movej([{joints}], a={s.acceleration:g}, v={s.speed:g})",
            f"  sleep({s.dwell:g})",
        ]
    return lines + ["end"]


def _axes(q_deg: np.ndarray) -> list[tuple[str, float]]:
    """KRL axis names and values of one configuration (deg): A1..A6, and E1 for a 7-axis arm's third joint."""
    if len(q_deg) == 7:
        robot = np.delete(q_deg, EXTERNAL_JOINT)
        return [(f"A{j + 1}", v) for j, v in enumerate(robot)] + [("E1", q_deg[EXTERNAL_JOINT])]
    return [(f"A{j + 1}", v) for j, v in enumerate(q_deg)]


def _krl(c: Configurations, s: Settings, header: list[str]) -> list[str]:
    n = c.q.shape[1]
    lines = ["&ACCESS RVP", f"DEF {s.name}()"] + [f"; {h}" for h in header]
    robot_axes = n - 1 if n == 7 else n
    for j in range(1, robot_axes + 1):
        lines += [f"  $VEL_AXIS[{j}] = {s.speed:g}", f"  $ACC_AXIS[{j}] = {s.acceleration:g}"]
    if n == 7:
        lines += [f"  $VEL_EXTAX[1] = {s.speed:g}", f"  $ACC_EXTAX[1] = {s.acceleration:g}"]
    for point, i in enumerate(range(len(c.q)), start=1):
        axes = ", ".join(f"{name} {_number(v, DEG_DECIMALS)}" for name, v in _axes(np.degrees(c.q[i])))
        lines += [f"  ; {_comment(point, c, i)}", f"  PTP {{{axes}}}", f"  WAIT SEC {s.dwell:g}"]
    return lines + ["END"]


def _rapid(c: Configurations, s: Settings, header: list[str]) -> list[str]:
    lines = [f"MODULE {s.name}"] + [f"  ! {h}" for h in header]
    lines += ["  PROC main()", f"    VelSet {s.speed:g}, 5000;", f"    AccSet {s.acceleration:g}, 100;"]
    for point, i in enumerate(range(len(c.q)), start=1):
        q_deg = np.degrees(c.q[i])
        external = [RAPID_UNUSED] * 6
        if len(q_deg) == 7:
            external[0] = _number(q_deg[EXTERNAL_JOINT], DEG_DECIMALS)
            q_deg = np.delete(q_deg, EXTERNAL_JOINT)
        robot = ", ".join(_number(v, DEG_DECIMALS) for v in q_deg)
        lines += [
            f"    ! {_comment(point, c, i)}",
            f"    MoveAbsJ [[{robot}], [{', '.join(external)}]]\\NoEOffs, v1000, fine, tool0;",
            f"    WaitTime \\InPos, {s.dwell:g};",
        ]
    return lines + ["  ENDPROC", "ENDMODULE"]


WRITERS = {"urscript": _urscript, "krl": _krl, "rapid": _rapid}


def program_text(c: Configurations, fmt: str, settings: Settings, header=()) -> str:
    """The program (text, one line per statement) visiting configurations c in their order;
    `header` lines become comments at its top. InputError for settings the format refuses, or
    a joint count it cannot write (URScript: 6; KRL and RAPID: 6, or 7 with the third joint
    as the external axis)."""
    if fmt not in WRITERS:
        raise InputError(f"unknown format {fmt!r}: one of {', '.join(FORMATS)}", key="format")
    n = c.q.shape[1]
    if n not in ((6,) if fmt == "urscript" else (6, 7)):
        raise InputError(
            f"{fmt} programs are written for 6{'' if fmt == 'urscript' else ' or 7'} joints, the robot has {n}",
            key="format",
        )
    _check_settings(fmt, settings)
    header = list(header) + [
        f"{len(c.q)} configurations; joints in {'rad' if fmt == 'urscript' else 'deg'}; "
        f"dwell {settings.dwell:g} s at each for the measurement",
        "check this program on the robot's simulator before running it: no collision check beyond the "
        "planner's capsule model",
    ]
    text = "\n".join(WRITERS[fmt](c, settings, header)) + "\n"
    if fmt == "krl":  # a self-check against a grammar that is not the reader below
        try:
            check_krl(text, settings.name, f"{settings.name}.src")
        except InputError as error:
            raise RuntimeError(f"remaster wrote KRL outside its own grammar (a bug): {error}") from error
    return text


def controller_table(c: Configurations, fmt: str) -> pd.DataFrame:
    """The configurations in program order as `remaster import` reads a controller log: point
    (1-based, the program's order and the key a sensor's export names), plan_row, set, pose,
    solution, q1..qN (rad, the values the program commands)."""
    table = pd.DataFrame(
        {
            "point": np.arange(1, len(c.q) + 1, dtype=np.int64),
            "plan_row": c.rows,
            "set": pd.Series(c.set, dtype=object),
            "pose": c.pose,
            "solution": c.solution,
        }
    )
    commanded = printed(c.q, fmt)
    for j in range(c.q.shape[1]):
        table[f"q{j + 1}"] = commanded[:, j]
    return table


# --------------------------------------------------------------------------- reading back


@dataclass(frozen=True)
class ParsedProgram:
    """A program read back: q (n, N) rad in program order; points (n,) and plan_rows (n,) from
    the comment before each move (-1 where a move has none)."""

    q: np.ndarray
    points: np.ndarray
    plan_rows: np.ndarray


_COMMENT = re.compile(r"point (\d+): plan row (\d+)")
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_MOVES = {
    "urscript": re.compile(r"^\s*movej\(\s*\[([^\]]*)\]"),
    "krl": re.compile(r"^\s*PTP\s*\{([^}]*)\}", re.I),
    "rapid": re.compile(r"^\s*MoveAbsJ\s*\[\[([^\]]*)\]\s*,\s*\[([^\]]*)\]\]", re.I),
}
_COMMENT_MARK = {"urscript": "#", "krl": ";", "rapid": "!"}


def _floats(text: str, where: str, source: str) -> list[float]:
    cells = [t.strip() for t in text.split(",")]
    if not all(re.fullmatch(_NUMBER, t) for t in cells):
        raise InputError(f"{where}: not a list of numbers: {quoted(text.strip())}", file=source)
    return [float(t) for t in cells]


def _krl_joints(text: str, where: str, source: str) -> list[float]:
    values = {}
    for item in text.split(","):
        match = re.fullmatch(rf"\s*(?:E6AXIS\s*:|AXIS\s*:)?\s*([AE]\d)\s+({_NUMBER})\s*", item, re.I)
        if not match:
            raise InputError(f"{where}: cannot read axis value {quoted(item.strip())}", file=source)
        values[match.group(1).upper()] = float(match.group(2))
    robot = [values.get(f"A{j}") for j in range(1, 7)]
    if None in robot or set(values) - {f"A{j}" for j in range(1, 7)} - {"E1"}:
        raise InputError(f"{where}: needs A1..A6 (and E1 for a 7-axis arm), got {', '.join(values)}", file=source)
    if "E1" in values:
        robot.insert(EXTERNAL_JOINT, values["E1"])
    return np.radians(robot).tolist()


def _rapid_joints(robot: str, external: str, where: str, source: str) -> list[float]:
    joints = _floats(robot, where, source)
    extra = _floats(external, where, source)
    if len(joints) != 6 or len(extra) != 6:
        raise InputError(f"{where}: a jointtarget has 6 robot and 6 external axes", file=source)
    if extra[0] < 8.9e9:
        joints.insert(EXTERNAL_JOINT, extra[0])
    return np.radians(joints).tolist()


def parse_program(text: str, fmt: str, source: str = "program") -> ParsedProgram:
    """Joint values (rad) of every move of a program in `fmt`, in order, and the point and plan
    row of the comment before each. InputError naming `source` and the 1-based line for a move
    that cannot be read, moves of different joint counts, or no move at all."""
    if fmt not in _MOVES:
        raise InputError(f"unknown format {fmt!r}: one of {', '.join(FORMATS)}", key="format")
    q, points, rows = [], [], []
    pending = (-1, -1)
    for number, line in enumerate(text.splitlines(), start=1):
        where = f"line {number}"
        stripped = line.strip()
        if stripped.startswith(_COMMENT_MARK[fmt]):
            found = _COMMENT.search(stripped)
            if found:
                pending = (int(found.group(1)), int(found.group(2)))
            continue
        move = _MOVES[fmt].match(line)
        if not move:
            continue
        if fmt == "urscript":
            joints = _floats(move.group(1), where, source)
        elif fmt == "krl":
            joints = _krl_joints(move.group(1), where, source)
        else:
            joints = _rapid_joints(move.group(1), move.group(2), where, source)
        if q and len(joints) != len(q[0]):
            raise InputError(f"{where}: {len(joints)} joints, the first move has {len(q[0])}", file=source)
        q.append(joints)
        points.append(pending[0])
        rows.append(pending[1])
        pending = (-1, -1)
    if not q:
        raise InputError(f"no {fmt} joint move found", file=source)
    return ParsedProgram(np.array(q, dtype=float), np.array(points, dtype=np.int64), np.array(rows, dtype=np.int64))


def check_program(text: str, fmt: str, c: Configurations, source: str = "program") -> float:
    """Read a program back and compare it with configurations c in their order: same number of
    moves, the same plan rows, and joint values within half a printed unit (plus float
    rounding). Returns the largest difference (rad); InputError naming the first move that
    differs."""
    parsed = parse_program(text, fmt, source)
    if len(parsed.q) != len(c.q) or not np.array_equal(parsed.plan_rows, c.rows):
        raise InputError(
            f"reads back as {len(parsed.q)} moves of plan rows {parsed.plan_rows[:10].tolist()}..., "
            f"not the {len(c.q)} configurations {c.rows[:10].tolist()}...",
            file=source,
        )
    unit = 10.0**-RAD_DECIMALS if fmt == "urscript" else np.radians(10.0**-DEG_DECIMALS)
    difference = np.abs(parsed.q - c.q)
    wrong = np.flatnonzero(np.any(difference > 0.5 * unit + 1e-12, axis=1))
    if wrong.size:
        raise InputError(
            f"move {wrong[0] + 1} reads back {np.degrees(difference[wrong[0]]).max():.3g} deg off", file=source
        )
    return float(difference.max())


@dataclass(frozen=True)
class RobotProgram:
    """A program ready to write: its text, the controller table in its order (`controller_table`),
    what its check found ('' unchecked) and a line saying what it visits and how far the joints travel."""

    text: str
    table: pd.DataFrame
    checked: str
    summary: str


def robot_program(
    given: Configurations, fmt: str, settings: Settings, order: str, header: list[str], check: bool, source: str
) -> RobotProgram:
    """The program visiting `given` in `order` ('tour': `joint_tour.joint_tour`; 'as-given'), read
    back and compared with the configurations first when `check` (InputError naming `source` when
    it does not read back)."""
    tour = joint_tour(given.q, order)
    as_given = joint_tour(given.q, "as-given")
    ordered = given.take(tour.order)
    text = program_text(ordered, fmt, settings, header=header)
    checked = ""
    if check:
        worst = check_program(text, fmt, ordered, source)
        checked = f"reads back as the {len(ordered.q)} configurations in order, to {np.degrees(worst):.2g} deg"
    summary = (
        f"{len(ordered.q)} configurations ({fmt}, order {order}): joint travel "
        f"{np.degrees(tour.total):.1f} deg in all (the largest joint motion of each move, summed), largest move "
        f"{np.degrees(tour.largest):.1f} deg; as given {np.degrees(as_given.total):.1f} and "
        f"{np.degrees(as_given.largest):.1f} deg"
    )
    return RobotProgram(text, controller_table(ordered, fmt), checked, summary)
