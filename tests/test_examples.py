"""The scripts of examples/ run as a user runs them (`python examples/<name>.py` from the
repository root) and print what their docstrings promise."""

import re
import subprocess
import sys

import pytest

from .conftest import REPO


def run(name: str) -> str:
    done = subprocess.run(
        [sys.executable, str(REPO / "examples" / f"{name}.py")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_plan_campaign_plans_configurations_that_move_every_joint_but_the_held_one():
    out = run("plan_campaign")
    found = re.search(r"(\d+) configurations of (\d+) poses", out)
    assert found and int(found[1]) >= int(found[2]) > 0
    moved = [float(v) for v in out.split("moves through: ")[1].split(", ")]
    assert moved[2] == 0.0 and min(moved[:2] + moved[3:]) > 0.5  # joint 3 held at 0


@pytest.mark.slow
def test_calibrate_ur5_prints_its_effects_its_validation_and_its_verdict():
    out = run("calibrate_ur5")
    assert "campaign: jacobi-ur5-gts3800, sensor: laser_tracker" in out
    before, after = map(float, re.search(r"validation RMSE: ([\d.]+) mm .*, ([\d.]+) mm", out).groups())
    assert after < before  # the effects the loop added lower the validation error
    assert re.search(r"^verdict: (pass|fail|not tested)$", out, re.MULTILINE)
    corrections = re.findall(r"^  joint\d: (.*)$", out, re.MULTILINE)
    assert len(corrections) == 6 and corrections[0].startswith("held")  # the UR5's base joint: no sensor sees it
    # a number with its U, or "not determined" naming the combination the data determine
    assert all(
        re.fullmatch(r"[+-][\d.]+ deg, U [\d.]+ deg|not determined: .*the data determine .*", c)
        for c in corrections[1:5]
    )


@pytest.mark.slow
def test_predict_at_tool_predicts_and_compensates_at_the_tool():
    out = run("predict_at_tool")
    assert "tool (0.0, 0.0, 0.15) m" in out
    reached = re.search(r"compensated: (\d+) of 5 targets reached", out)
    assert reached and int(reached[1]) == 5


@pytest.mark.slow
def test_compare_campaigns_compares_the_zero_offsets_and_the_predictions():
    out = run("compare_campaigns")
    assert "kuka-twin-2019: effects" in out and "kuka-twin: effects" in out
    offsets = out.split("zero-offset drift (loop-closed model):")[1].split("predicted positions")[0]
    assert re.search(r"zero_offsets\.\S+\s+deg\s+-?\d", offsets)  # compared: numbers, not NaN
    assert re.search(r"^\s*(paper|loop)\s", out.split("drift across the joint space:")[1], re.MULTILINE)
