"""`remaster program`: each format (URScript, KRL, RAPID) is written and read back to the same joint
values and order; the joint tour shortens the joint travel and keeps every configuration once; bad
configurations are refused naming the file, column and rows; and a plan becomes a program, and the
program's table becomes a campaign through `remaster import`."""

from __future__ import annotations

import errno
import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from remaster import cli, files
from remaster.campaigns import folders
from remaster.errors import InputError
from remaster.planning import joint_tour, krl_grammar, programs
from remaster.robot import kinematics

from ..conftest import IIWA_URDF, UR5_URDF

FRAMES = {"iiwa": (IIWA_URDF, "iiwa_link_0", "iiwa_link_ee"), "ur5": (UR5_URDF, None, None)}
HALF_UNIT = {"urscript": 0.5e-6, "krl": np.radians(0.5e-4), "rapid": np.radians(0.5e-4)}  # rad
SETTINGS = {fmt: programs.Settings(*programs.DEFAULT_MOTION[fmt], dwell=2.0) for fmt in programs.FORMATS}


@pytest.fixture(scope="module")
def ur5():
    return kinematics.chain_from_urdf(UR5_URDF.read_text(), None, None, source=str(UR5_URDF))


def table_of(q) -> pd.DataFrame:
    q = np.atleast_2d(q)
    table = pd.DataFrame({"set": "optimization", "pose": np.arange(len(q)), "solution": 0})
    for j in range(q.shape[1]):
        table[f"q{j + 1}"] = q[:, j]
    return table


def random_within_limits(chain, n, rng, span=np.pi) -> np.ndarray:
    low = np.maximum(chain.lower, -span)
    high = np.minimum(chain.upper, span)
    return rng.uniform(low, high, (n, chain.n_joints))


# --------------------------------------------------------------------------- formats


@pytest.mark.parametrize(
    "fmt, robot", [("urscript", "ur5"), ("krl", "ur5"), ("krl", "iiwa"), ("rapid", "ur5"), ("rapid", "iiwa")]
)
def test_each_format_reads_back_to_the_joint_values_and_order(fmt, robot, ur5, iiwa, rng):
    chain = ur5 if robot == "ur5" else iiwa
    q = random_within_limits(chain, 40, rng)
    given = programs.configurations(table_of(q), chain, "plan.csv", "robot.urdf")
    ordered = given.take(rng.permutation(len(q)))
    text = programs.program_text(ordered, fmt, SETTINGS[fmt])
    if fmt == "krl":  # a grammar that is not the reader below accepts it
        assert krl_grammar.check_krl(text, SETTINGS[fmt].name, "prog") == 40
    parsed = programs.parse_program(text, fmt, "prog")
    assert parsed.points.tolist() == list(range(1, 41))
    assert np.array_equal(parsed.plan_rows, ordered.rows)
    # to the printed precision: half a unit of the last decimal (1e-6 rad; 1e-4 deg)
    assert np.abs(parsed.q - ordered.q).max() <= HALF_UNIT[fmt] + 1e-12
    assert np.abs(parsed.q - ordered.q).max() > 0  # the values were rounded, so the check can see
    np.testing.assert_allclose(parsed.q, programs.printed(ordered.q, fmt), rtol=0, atol=1e-12)
    assert programs.check_program(text, fmt, ordered) <= HALF_UNIT[fmt] + 1e-12
    # the controller table holds exactly what the program commands, in its order
    table = programs.controller_table(ordered, fmt)
    assert table["point"].tolist() == list(range(1, 41)) and np.array_equal(table["plan_row"], ordered.rows)
    np.testing.assert_allclose(table[[f"q{j + 1}" for j in range(chain.n_joints)]], parsed.q, rtol=0, atol=1e-12)


def test_a_known_configuration_is_printed_as_known_strings(ur5, iiwa):
    six = programs.configurations(table_of([0.0, np.pi / 2, -np.pi / 4, np.pi, 1.0, -0.5]), ur5, "p.csv", "u")
    ur = programs.program_text(six, "urscript", SETTINGS["urscript"]).splitlines()
    assert "  movej([0.000000, 1.570796, -0.785398, 3.141593, 1.000000, -0.500000], a=0.5, v=0.5)" in ur
    assert "  sleep(2)" in ur and ur[0] == "def remaster_campaign():" and ur[-1] == "end"  # def in column 1 of line 1
    assert ur.index("def remaster_campaign():") < ur.index("  # point 1: plan row 0 (optimization pose 0 solution 0)")
    krl = programs.program_text(six, "krl", programs.Settings(20, 30, 1.5, "cell3")).splitlines()
    assert "  PTP {A1 0.0000, A2 90.0000, A3 -45.0000, A4 180.0000, A5 57.2958, A6 -28.6479}" in krl
    assert krl[1] == "DEF cell3()" and krl[-1] == "END" and "  WAIT SEC 1.5" in krl
    assert "  $VEL_AXIS[6] = 20" in krl and "  $ACC_AXIS[1] = 30" in krl and not any("EXTAX" in s for s in krl)
    # a 7-axis arm: the third joint is the external axis E1 / eax_a
    seven = programs.configurations(table_of(np.radians([10, 20, 30, 40, 50, 60, -70])), iiwa, "p.csv", "i")
    krl7 = programs.program_text(seven, "krl", SETTINGS["krl"]).splitlines()
    assert "  PTP {A1 10.0000, A2 20.0000, A3 40.0000, A4 50.0000, A5 60.0000, A6 -70.0000, E1 30.0000}" in krl7
    assert "  $VEL_EXTAX[1] = 20" in krl7
    assert krl_grammar.check_krl("\n".join(krl), "cell3") == krl_grammar.check_krl("\n".join(krl7)) == 1
    rapid = programs.program_text(seven, "rapid", SETTINGS["rapid"]).splitlines()
    assert (
        "    MoveAbsJ [[10.0000, 20.0000, 40.0000, 50.0000, 60.0000, -70.0000], [30.0000, 9E9, 9E9, 9E9, 9E9, 9E9]]"
        "\\NoEOffs, v1000, fine, tool0;"
    ) in rapid
    assert "    WaitTime \\InPos, 2;" in rapid and rapid[0] == "MODULE remaster_campaign" and rapid[-1] == "ENDMODULE"
    rapid6 = programs.program_text(six, "rapid", SETTINGS["rapid"])
    assert "[[0.0000, 90.0000, -45.0000, 180.0000, 57.2958, -28.6479], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]]" in rapid6
    # a tiny negative angle prints as 0, not -0
    assert "A1 0.0000" in programs.program_text(
        programs.configurations(table_of([-1e-9, 0, 0, 0, 0, 0]), ur5, "p.csv", "u"), "krl", SETTINGS["krl"]
    )


@pytest.mark.parametrize("robot", ["ur5", "iiwa"])
@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # the checker calls pyparsing's older names
def test_rapid_programs_pass_a_rapid_checker_the_project_did_not_write(robot, request, rng):
    """rapidchecker (PyPI: ABB RAPID grammar, indentation, keyword case, whitespace) accepts the
    module as written and catches each of three broken copies, so the check has teeth."""
    from rapidchecker.cli import check_file

    chain = request.getfixturevalue(robot)
    configs = programs.configurations(table_of(random_within_limits(chain, 6, rng)), chain, "p.csv", robot)
    module = programs.program_text(configs, "rapid", SETTINGS["rapid"])
    assert check_file(module) == []
    broken = {
        "a move without its semicolon": module.replace("tool0;", "tool0", 1),
        "a procedure never ended": module.replace("  ENDPROC\n", ""),
        "a keyword in lower case": module.replace("ENDMODULE", "endmodule"),
    }
    for what, text in broken.items():
        assert check_file(text), what


GOOD_KRL = (
    "&ACCESS RVP\nDEF cell3()\n; a comment\n  $VEL_AXIS[1] = 20\n  $ACC_EXTAX[1] = 20\n  ; point 1: plan row 0\n"
    "  PTP {A1 0.0000, A2 90.0000, A3 -45.0000, A4 180.0000, A5 57.2958, A6 -28.6479}\n  WAIT SEC 1.5\nEND\n"
)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda t: t.replace("\nEND\n", "\nENDX\n"), r"cell3.src: line 9: not a statement remaster's KRL has: 'ENDX'"),
        (
            lambda t: t.replace("\nEND\n", "\n"),
            r"cell3.src: line 8: the program ends without the END of DEF cell3\(\) \(line 2\)",
        ),
        (lambda t: t.replace("-28.6479}", "-28.6479"), r"cell3.src: line 7: unbalanced braces: 'PTP \{A1 0.0000, "),
        (lambda t: t.replace("A6 -28", "A7 -28"), r"cell3.src: line 7: unknown axis 'A7': one of A1, A2, .*, E1"),
        (lambda t: t.replace("A5 57.2958", "A5 57,2958"), r"cell3.src: line 7: not an axis and its value: '2958'"),
        (lambda t: t.replace("A5 57.2958", "A5 5x7"), r"cell3.src: line 7: the value of A5 is not a number: '5x7'"),
        (lambda t: t.replace("SEC 1.5", "SEC"), r"cell3.src: line 8: not a statement remaster's KRL has: 'WAIT SEC'"),
        (lambda t: t.replace("= 20\n", "= fast\n", 1), r"cell3.src: line 4: \$VEL_AXIS\[1\] is not a number: 'fast'"),
        (lambda t: t.replace("A2 90.0000, ", ""), r"cell3.src: line 7: .* every robot axis: A2 missing"),
        (lambda t: t.replace("DEF cell3", "DEF cell4"), r"cell3.src: line 2: DEF cell4\(\) in a program named 'cell3'"),
        (lambda t: t + "HALT\n", r"cell3.src: line 10: after the END of DEF cell3\(\): 'HALT'"),
        (lambda t: t.replace("&ACCESS RVP\n", "PTP {A1 0}\n"), r"cell3.src: line 1: expected DEF <name>\(\)"),
        (lambda t: "; nothing\n", r"cell3.src: no DEF <name>\(\) line: not a KRL program"),
    ],
    ids=[
        "ENDX",
        "no-END",
        "brace",
        "axis",
        "comma",
        "number",
        "wait",
        "variable",
        "A2",
        "name",
        "after",
        "before",
        "empty",
    ],  # fmt: skip
)
def test_a_krl_program_outside_the_grammar_is_refused_naming_its_line(change, message):
    """krl_grammar accepts what `remaster program` writes and refuses, naming the line, each of
    these broken copies, which remaster's own reader (parse_program) would read or skip."""
    assert krl_grammar.check_krl(GOOD_KRL, "cell3", "cell3.src") == 1
    assert krl_grammar.check_krl(GOOD_KRL.lower(), "CELL3") == 1  # KRL's keywords and names are in any case
    with pytest.raises(InputError, match=message):
        krl_grammar.check_krl(change(GOOD_KRL), "cell3", "cell3.src")


def test_a_writer_regression_is_caught_by_the_grammar_before_the_program_is_returned(ur5, monkeypatch):
    six = programs.configurations(table_of(np.zeros(6)), ur5, "p.csv", "u")
    writer = programs.WRITERS["krl"]
    monkeypatch.setitem(programs.WRITERS, "krl", lambda c, s, h: writer(c, s, h)[:-1] + ["ENDX"])
    with pytest.raises(RuntimeError, match=r"outside its own grammar \(a bug\): cell3.src: line \d+: .*'ENDX'"):
        programs.program_text(six, "krl", programs.Settings(20, 20, 2, "cell3"))


def test_formats_and_settings_the_robot_cannot_take_are_refused(ur5, iiwa):
    seven = programs.configurations(table_of(np.zeros(7)), iiwa, "p.csv", "i")
    with pytest.raises(InputError, match="urscript programs are written for 6 joints, the robot has 7"):
        programs.program_text(seven, "urscript", SETTINGS["urscript"])
    six = programs.configurations(table_of(np.zeros(6)), ur5, "p.csv", "u")
    with pytest.raises(InputError, match="speed: is a percentage for krl: at most 100, got 150"):
        programs.program_text(six, "krl", programs.Settings(150, 20, 2))
    with pytest.raises(InputError, match="dwell: must be a positive number, got -1"):
        programs.program_text(six, "rapid", programs.Settings(20, 20, -1))
    with pytest.raises(InputError, match="acceleration: RAPID's AccSet takes at least 20 %"):
        programs.program_text(six, "rapid", programs.Settings(20, 10, 2))
    with pytest.raises(InputError, match="'2nd_cell' is not a KRL name"):
        programs.program_text(six, "krl", programs.Settings(20, 20, 2, "2nd_cell"))


def test_parser_errors_name_the_line():
    with pytest.raises(InputError, match="prog: line 2: not a list of numbers: '0.1, x, 0.3"):
        programs.parse_program("def f():\n  movej([0.1, x, 0.3, 0, 0, 0], a=1, v=1)\nend\n", "urscript", "prog")
    with pytest.raises(InputError, match="line 3: 5 joints, the first move has 6"):
        programs.parse_program("movej([0,0,0,0,0,0])\n# c\nmovej([0,0,0,0,0])\n", "urscript", "prog")
    with pytest.raises(InputError, match=r"line 1: needs A1..A6 \(and E1 for a 7-axis arm\), got A1, A2"):
        programs.parse_program("PTP {A1 0, A2 0}\n", "krl", "prog")
    with pytest.raises(InputError, match="prog: no rapid joint move found"):
        programs.parse_program("MODULE m\nENDMODULE\n", "rapid", "prog")


# --------------------------------------------------------------------------- ordering


def test_configurations_on_a_line_are_visited_in_sequence():
    """Known answer: joint 1 at 0, 1, ..., 9 deg, shuffled, starting at 0: the shortest path
    visits them in sequence, 9 moves of 1 deg."""
    rng = np.random.default_rng(1)
    steps = np.concatenate([[0], rng.permutation(np.arange(1, 10))])
    q = np.zeros((10, 6))
    q[:, 0] = np.radians(steps)
    tour = joint_tour.joint_tour(q)
    assert steps[tour.order].tolist() == list(range(10))
    assert tour.total == pytest.approx(np.radians(9)) and tour.largest == pytest.approx(np.radians(1))


def test_the_tour_shortens_joint_travel_and_keeps_every_configuration_once(ur5):
    for seed in range(5):
        rng = np.random.default_rng(seed)
        q = random_within_limits(ur5, 60, rng)
        given = joint_tour.joint_tour(q, "as-given")
        greedy = joint_tour.move_costs(q, joint_tour.greedy_order(q)).sum()
        tour = joint_tour.joint_tour(q)
        assert sorted(tour.order.tolist()) == list(range(60)) and tour.order[0] == 0
        assert tour.total <= greedy + 1e-12 < given.total
        assert tour.total == pytest.approx(joint_tour.move_costs(q, tour.order).sum())


def test_two_opt_leaves_no_improving_reversal(rng):
    q = rng.uniform(-np.pi, np.pi, (12, 6))
    order = joint_tour.joint_tour(q).order
    cost = joint_tour.move_costs(q, order).sum()
    for i, k in itertools.combinations(range(1, 12), 2):
        turned = order.copy()
        turned[i : k + 1] = turned[i : k + 1][::-1]
        assert joint_tour.move_costs(q, turned).sum() >= cost - 1e-9


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "change, message",
    [
        (
            lambda t: t.drop(columns="q6"),
            r"plan.csv: q6: missing joint column\(s\) \(the robot has 6 joints; got: set, pose, solution, q1, q2, q3, q4, q5, q1_deg\)",
        ),
        (lambda t: t.assign(q7=0.0), r"plan.csv: q7: more joint columns than the robot's 6 joints \(ur5.urdf\)"),
        (lambda t: t.assign(q3=[0.1, np.nan, 0.2, "x"]), r"plan.csv: q3: not a finite number \(rows 1, 3\)"),
        (
            lambda t: t.assign(q2=[10.0, 0.0, 0.0, 90.0]),
            r"plan.csv: q2: beyond the limits \[-6.283, 6.283\] rad of joint joint2 in ur5.urdf "
            r"\(configurations are in rad\) \(rows 0, 3\)",
        ),
        (lambda t: t.assign(q1_deg=[0.0, 0.0, 5.0, 0.0]), r"plan.csv: q1_deg: disagrees with q1 \(rad\).*\(row 2\)"),
        (lambda t: t.assign(set=["optimization", "test", "validation", "x"]), r"plan.csv: set: unknown set.*rows 1, 3"),
        (
            lambda t: t.assign(pose=[0, 0, 1, 2]),
            r"plan.csv: set, pose, solution: repeated: each \(set, pose, solution\) may appear once \(rows 0, 1\)",
        ),
        (lambda t: t.assign(pose=[0, 1.5, 2, 3]), r"plan.csv: pose: not a non-negative integer \(row 1\)"),
        (lambda t: t.iloc[:0], r"plan.csv: no configurations \(no rows\)"),
    ],
    ids=["missing", "extra", "nan", "limits", "deg", "set", "repeated", "pose", "empty"],
)
def test_bad_configurations_name_file_column_and_rows(change, message, ur5):
    table = table_of(np.zeros((4, 6))).assign(q1_deg=0.0)
    with pytest.raises(InputError, match=message):
        programs.configurations(change(table), ur5, "plan.csv", "ur5.urdf")


# --------------------------------------------------------------------------- command line


def program_args(robot, configurations, fmt, out, *extra):
    urdf, base, flange = FRAMES[robot]
    frames = [] if base is None else ["--base", base, "--flange", flange]
    return ["program", "--urdf", str(urdf), *frames, "--configurations", str(configurations), "--format", fmt,
            "--out", str(out), *extra]  # fmt: skip


def test_a_plan_becomes_a_program_and_its_table_a_campaign(tmp_path, iiwa, capsys):
    """End to end: `remaster plan` -> `remaster program --format krl --check` -> read the program
    back -> its table and a tracker's export of the points -> `remaster import`: the campaign
    holds the planned configurations (to the printed precision) in the program's order."""
    plan = tmp_path / "plan.csv"
    urdf, base, flange = FRAMES["iiwa"]
    status = cli.main(
        ["plan", "--urdf", str(urdf), "--base", base, "--flange", flange, "--sensor-origin", "1.6", "0.5", "1.0",
         "--marker", "-0.1", "0", "0.02", "--candidates", "20", "--seed", "3", "--out", str(plan)]
    )  # fmt: skip
    assert status == 0
    out = tmp_path / "cell3.src"
    assert cli.main(program_args("iiwa", plan, "krl", out, "--check", "--dwell", "3")) == 0
    said = capsys.readouterr().out
    assert "reads back as the" in said and "as given" in said and "simulator" in said
    planned = pd.read_csv(plan)
    names = [f"q{j}" for j in range(1, 8)]
    parsed = programs.parse_program(out.read_text(), "krl", str(out))
    assert krl_grammar.check_krl(out.read_text(), out.stem, str(out)) == len(planned)
    assert sorted(parsed.plan_rows.tolist()) == list(range(len(planned)))  # every row once
    np.testing.assert_allclose(parsed.q, planned[names].to_numpy()[parsed.plan_rows], rtol=0, atol=HALF_UNIT["krl"])
    assert "DEF cell3()" in out.read_text() and "WAIT SEC 3" in out.read_text()
    tour_total = joint_tour.move_costs(planned[names].to_numpy(), parsed.plan_rows).sum()
    assert tour_total < joint_tour.move_costs(planned[names].to_numpy()).sum()

    table = pd.read_csv(tmp_path / "cell3.csv")
    marker = np.array([-0.1, 0.0, 0.02])
    xyz = kinematics.marker_positions(iiwa, table[names].to_numpy(), marker) - [1.6, 0.5, 1.0]
    tracker = pd.DataFrame({"id": table["point"][::-1], "X": 1e3 * xyz[::-1, 0], "Y": 1e3 * xyz[::-1, 1]})
    tracker["Z"] = 1e3 * xyz[::-1, 2]
    tracker.to_csv(tmp_path / "tracker.csv", index=False)
    config = {
        "name": "planned",
        "date": "2026-11-26",
        "description": "a planned campaign",
        "robot": {"urdf": str(urdf), "base": base, "flange": flange},
        "controller": {
            "file": "cell3.csv",
            "joints": names,
            "unit": "rad",
            "set": "set",
            "pose": "pose",
            "solution": "solution",
            "key": "point",
        },  # fmt: skip
        "sensors": {
            "laser_tracker": {
                "kind": "laser_tracker",
                "marker": marker.tolist(),
                "noise": 1e-5,
                "file": "tracker.csv",
                "xyz": ["X", "Y", "Z"],
                "unit": "mm",
                "match": "key",
                "key": "id",
            }  # fmt: skip
        },
    }
    files.write_yaml(tmp_path / "import.yaml", config)
    folder, report = folders.import_campaign(tmp_path / "import.yaml", tmp_path / "raw", repo_root=tmp_path)
    assert report["sensors"]["laser_tracker"]["matched"] == len(planned)
    imported = folders.read_campaign(folder, repo_root=tmp_path).sensors["laser_tracker"].table
    np.testing.assert_allclose(imported[names].to_numpy(), parsed.q, rtol=0, atol=1e-12)
    key = ["set", "pose", "solution"]
    back = imported[key].merge(planned[key].reset_index(), on=key, how="left")["index"].to_numpy()
    assert np.array_equal(back, parsed.plan_rows)  # each campaign row is its plan row
    np.testing.assert_allclose(imported[["x", "y", "z"]].to_numpy(), xyz, rtol=0, atol=1e-9)


def test_the_command_line_writes_urscript_as_given(tmp_path, ur5, rng):
    q = random_within_limits(ur5, 8, rng)
    table_of(q).to_csv(tmp_path / "mine.csv", index=False)
    out = tmp_path / "cell.script"
    args = program_args("ur5", tmp_path / "mine.csv", "urscript", out, "--order", "as-given", "--speed", "0.3")
    assert cli.main([*args, "--table", str(tmp_path / "t.csv")]) == 0
    parsed = programs.parse_program(out.read_text(), "urscript")
    assert parsed.plan_rows.tolist() == list(range(8)) and "v=0.3)" in out.read_text()
    np.testing.assert_allclose(parsed.q, q, rtol=0, atol=HALF_UNIT["urscript"])
    assert pd.read_csv(tmp_path / "t.csv")["point"].tolist() == list(range(1, 9))


def test_the_command_line_refuses_bad_input_and_writes_nothing(tmp_path, capsys):
    table = table_of(np.radians([[0, 30, 0, -60, 0, 60, 0], [0, 30, 0, -60, 0, 60, 0]]))
    table.loc[1, "q4"] = -130.0  # degrees for radians
    table.to_csv(tmp_path / "bad.csv", index=False)
    out = tmp_path / "cell.src"
    assert cli.main(program_args("iiwa", tmp_path / "bad.csv", "krl", out)) == 2
    error = capsys.readouterr().err
    assert error.startswith(f"remaster program: error: {tmp_path / 'bad.csv'}: q4: beyond the limits")
    assert "of joint iiwa_joint_4 in" in error and "(row 1)" in error
    table.loc[1, "q4"] = -1.0
    table.to_csv(tmp_path / "good.csv", index=False)
    assert cli.main(program_args("iiwa", tmp_path / "good.csv", "urscript", out)) == 2
    assert "urscript programs are written for 6 joints, the robot has 7" in capsys.readouterr().err
    assert cli.main(program_args("iiwa", tmp_path / "good.csv", "krl", tmp_path / "1st.src")) == 2
    assert "not a KRL name" in capsys.readouterr().err
    assert cli.main(program_args("iiwa", tmp_path / "missing.csv", "rapid", tmp_path / "p.mod")) == 2
    assert "missing.csv: file not found" in capsys.readouterr().err
    # a program or table that would overwrite the configurations (plan.csv -> plan.src, plan.csv)
    assert cli.main(program_args("iiwa", tmp_path / "good.csv", "krl", tmp_path / "good.src")) == 2
    assert "--table: would overwrite the configurations" in capsys.readouterr().err
    assert (
        cli.main(program_args("iiwa", tmp_path / "good.csv", "rapid", tmp_path / "good.csv", "--table", "t.csv")) == 2
    )
    assert "--out: would overwrite the configurations" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv", "good.csv"]
    assert pd.read_csv(tmp_path / "good.csv").shape == table.shape


def test_an_output_that_is_a_directory_or_on_a_full_disk_is_an_error_naming_it(tmp_path, capsys, monkeypatch):
    """`--out` naming a directory, and a disk that fills while the program is written, used to end in
    IsADirectoryError or OSError tracebacks (a full disk leaving half a program): exit 2, the file
    named, nothing written and no partial file left."""
    table_of(np.radians([[0, 30, 0, -60, 0, 60, 0]])).to_csv(tmp_path / "good.csv", index=False)
    (tmp_path / "out").mkdir()
    for option, args in (
        ("--out", program_args("iiwa", tmp_path / "good.csv", "krl", tmp_path / "out")),
        (
            "--table",
            program_args("iiwa", tmp_path / "good.csv", "krl", tmp_path / "p.src", "--table", tmp_path / "out"),
        ),
    ):
        assert cli.main([str(a) for a in args]) == 2
        assert capsys.readouterr().err == (
            f"remaster program: error: {option}: {tmp_path / 'out'} is a directory: give a file name\n"
        )
    write_text = Path.write_text

    def full_disk(self, text, *args, **kwargs):
        write_text(self, text[: len(text) // 2], *args, **kwargs)  # half of it reaches the disk
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "write_text", full_disk)
    assert cli.main(program_args("iiwa", tmp_path / "good.csv", "krl", tmp_path / "p.src")) == 2
    assert capsys.readouterr().err == (
        f"remaster program: error: {tmp_path / 'p.src'}: cannot write: No space left on device\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv", "out"]
    assert list((tmp_path / "out").iterdir()) == []


def test_the_iso9283_pose_test_is_planned_and_programmed_in_its_cycles(tmp_path, iiwa):
    """`remaster plan --objective iso9283`: the five ISO 9283 points of the cube, the flange at each
    (forward kinematics of the planned configuration, not the planner's own record), one orientation
    for all, each configuration commanded once per cycle P1..P5 for 30 cycles, so that a campaign of it
    gives RP per pose (5 groups of 30 cycles); `remaster program --order as-given` keeps the cycles."""
    from remaster.evaluation.iso9283 import pose_characteristics
    from remaster.loop.noise_floor import configuration_groups
    from remaster.robot import planning

    plan = tmp_path / "iso.csv"
    urdf, base, flange = FRAMES["iiwa"]
    status = cli.main(
        ["plan", "--urdf", str(urdf), "--base", base, "--flange", flange, "--sensor-origin", "1.6", "0.5", "1.0",
         "--marker", "-0.1", "0", "0.02", "--objective", "iso9283", "--cube-centre", "0.6", "0.2", "0.5",
         "--cube-edge", "0.2", "--set", "validation", "--out", str(plan)]
    )  # fmt: skip
    assert status == 0
    table = pd.read_csv(plan)
    names = [f"q{j}" for j in range(1, 8)]
    assert len(table) == 150 and table["pose"].is_unique and set(table["set"]) == {"validation"}
    assert table["iso_pose"].tolist()[:6] == ["P1", "P2", "P3", "P4", "P5", "P1"] and table["cycle"].max() == 30
    frames = kinematics.ForwardKinematics(iiwa, table[names].to_numpy()).flange_poses()
    points = planning.iso9283_points([0.6, 0.2, 0.5], 0.2)
    np.testing.assert_allclose(frames[:, :3, 3], np.tile(points, (30, 1)), atol=1e-9)
    np.testing.assert_allclose(
        frames[:, :3, :3], np.broadcast_to(frames[0, :3, :3], frames[:, :3, :3].shape), atol=1e-9
    )
    groups, counts = configuration_groups(table[names].to_numpy())
    assert counts.tolist() == [30] * 5
    rng = np.random.default_rng(0)
    characteristics = pose_characteristics(rng.normal(0.0, 1e-5, (150, 3)), groups)
    assert characteristics["RP"].notna().all() and (characteristics["cycles"] == 30).all()

    out = tmp_path / "iso_test.src"
    assert cli.main(program_args("iiwa", plan, "krl", out, "--order", "as-given")) == 0
    parsed = programs.parse_program(out.read_text(), "krl", str(out))
    assert parsed.plan_rows.tolist() == list(range(150)) and krl_grammar.check_krl(out.read_text(), "iso_test") == 150
    assert cli.main(["plan", "--urdf", str(urdf), "--base", base, "--flange", flange, "--sensor-origin", "1.6",
                     "0.5", "1.0", "--objective", "iso9283", "--cube-centre", "2.6", "0", "0.5", "--cube-edge",
                     "0.2", "--out", str(tmp_path / "far.csv")]) == 2  # fmt: skip
    assert not (tmp_path / "far.csv").exists()
