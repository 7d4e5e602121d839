"""Putting a calibration to work: predicted positions, compensated commands (exact under the
calibrated model, nearest to the nominal ones), bounds from the posterior, bad input, and the
closed loop on the simulator: compensated commands sent to the twin's true robot."""

import os
import re
import shutil
import time
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from remaster import audit, files, layout, spatial
from remaster import results as results_module
from remaster.calibration import compensation, prediction
from remaster.calibration.tool_link import ToolSplit
from remaster.campaigns import folders
from remaster.campaigns.scenario import robot_from_truth, sensor_from_truth
from remaster.campaigns.simulation import true_marker_positions, true_sensor_positions
from remaster.cli import main as cli
from remaster.errors import InputError
from remaster.inference import fit
from remaster.inference.gp.kernels import Hyperparameters
from remaster.inference.model import SIGMA
from remaster.inference.parameter_blocks import link_labels
from remaster.inference.posterior_summary import mode_summary
from remaster.inference.readings import ModelSettings
from remaster.results import check_made_from
from remaster.robot import kinematics
from remaster.robot.nearness import Nearness
from remaster.units import DEG, MM

from ..conftest import REPO
from ..evaluation.test_workspace import at_start, fitted, laplace_content

MARKER = np.array([0.0, 0.0, 0.08])
EFFECTS = ("joint_compliance", "marker_offset", "link_geometry")


def loop_values(chain, rng) -> dict:
    values = {f"zero_offsets.q{j + 1}": rng.normal(0.0, 0.3 * DEG) for j in range(chain.n_joints)}
    values.update({f"joint_compliance.q{j + 1}": rng.normal(0.0, 3e-5) for j in range(chain.n_joints)})
    values.update({f"marker_offset.{a}": rng.normal(0.0, 5e-4) for a in "xyz"})
    for _, column, name in link_labels(chain):
        values[name] = rng.normal(0.0, 5e-4 if column == 0 else 0.05 * DEG)
    return values


def synthetic_robot(chain, rng, spread=1e-5, draws=400, held=None, tcp=None, **given) -> compensation.CalibratedRobot:
    """A loop-closed model with random values (`given` ones replaced: zero_offsets_q4=0.01) and Gaussian
    posterior rows of std `spread` (SI) around them."""
    values = {**loop_values(chain, rng), **{k.replace("_q", ".q"): v for k, v in given.items()}}
    setup = {
        "registration.x": 0.8,
        "registration.y": -0.2,
        "registration.z": 0.1,
        "registration.alpha": 0.3,
        "registration.beta": -0.01,
        "registration.gamma": 0.02,
        "sensor_scale.s": 2e-5,
    }
    names = [n for n in values if n not in (held or {})]
    every = {**values, **setup}
    samples = pd.DataFrame({n: every[n] + spread * rng.standard_normal(draws) for n in names + list(setup)})
    samples[SIGMA] = 2e-5
    calibration = prediction.Calibration("loop", {**values, **(held or {})}, EFFECTS, ModelSettings(), samples[names])
    return compensation.CalibratedRobot(
        chain,
        calibration,
        MARKER if tcp is None else np.asarray(tcp),
        tcp is None,
        setup,
        spatial.homogeneous(spatial.rot_z(0.4), [1.0, 2.0, 0.5]),
        samples,
        dict(held or {}),
        0.5 * DEG,
        absorbed=frozenset(held or {}),
    )


def commands(chain, rng, n=12):
    return rng.uniform(np.maximum(chain.lower, -2.0) * 0.8, np.minimum(chain.upper, 2.0) * 0.8, (n, chain.n_joints))


# --------------------------------------------------------------------------- pieces


def test_the_flange_pose_carries_the_point(iiwa, rng):
    """Predictor.flange_poses (new) and Predictor.points (the fit's) agree: the link geometry and
    the joint-space effects act on the flange, the marker offset on the marker."""
    robot = synthetic_robot(iiwa, rng)
    q = commands(iiwa, rng)
    predictor = robot.predictor(q)
    values = robot.calibration.values
    poses = predictor.flange_poses(values)
    offset = np.array([values[f"marker_offset.{a}"] for a in "xyz"])
    np.testing.assert_allclose(
        poses[:, :3, :3] @ (MARKER + offset) + poses[:, :3, 3], predictor.points(values), atol=1e-12
    )


def test_sensor_frame_round_trip(iiwa, rng):
    robot = synthetic_robot(iiwa, rng)
    points = rng.uniform(-1, 1, (20, 3))
    np.testing.assert_allclose(robot.in_frame(robot.from_sensor(points), "sensor"), points, atol=1e-12)


def test_compensated_commands_put_the_calibrated_robot_where_the_nominal_one_was(iiwa, rng):
    """Under the calibrated model the compensated command reproduces the nominal command's point
    and flange orientation, and among all such commands it is the nearest to the nominal one
    (first-order optimality: the change lies in the row space of the constraint Jacobian)."""
    robot = synthetic_robot(iiwa, rng)
    q0 = commands(iiwa, rng)
    out = compensation.compensate(robot, "robot", 200, rng, commands=q0)
    assert (out["status"] == compensation.REACHED).all()
    q = out[[f"q{j + 1}" for j in range(7)]].to_numpy()
    nominal = kinematics.ForwardKinematics(iiwa, q0)
    np.testing.assert_allclose(robot.robot_points(q), nominal.points(MARKER), atol=2e-9)
    rotations = robot.predictor(q).flange_poses(robot.calibration.values)[:, :3, :3]
    np.testing.assert_allclose(rotations, nominal.flange_poses()[:, :3, :3], atol=2e-9)
    assert np.all(out["error_mm"] < 1e-5) and np.all(out["nominal_error_mm"] > 0.1)
    evaluate = compensation._calibrated_evaluate(robot)
    for i in range(3):
        base_points, base_frames = evaluate(q[i : i + 1])
        columns = []
        for j in range(7):
            step = q[i : i + 1].copy()
            step[0, j] += 1e-6
            p, r = evaluate(step)
            dr = r[0] @ base_frames[0].T  # I + skew(small rotation)
            columns.append(np.concatenate([(p - base_points)[0], [dr[2, 1], dr[0, 2], dr[1, 0]]]) / 1e-6)
        jacobian = np.array(columns).T  # (6, 7)
        change = q[i] - q0[i]
        null = np.linalg.svd(jacobian)[2][-1]  # the one direction that moves neither point nor flange
        assert abs(null @ change) < 1e-4 * np.linalg.norm(change)


def test_a_six_joint_robot_and_target_positions_with_seeds(rng, ur5_dh):
    """Target positions (robot frame) with seed commands on a DH robot: the nominal solution is
    the nominal model's IK of the point from the seed, the compensated one puts the calibrated
    point on the target."""
    robot = synthetic_robot(ur5_dh, rng)
    q_true = commands(ur5_dh, rng, 8)
    targets = kinematics.ForwardKinematics(ur5_dh, q_true).points(MARKER)
    out = compensation.compensate(robot, "robot", 100, rng, targets=targets, seeds=q_true + 0.05)
    assert (out["status"] == compensation.REACHED).all(), out["reason"].tolist()
    q = out[[f"q{j + 1}" for j in range(6)]].to_numpy()
    nominal = out[[f"nominal_q{j + 1}" for j in range(6)]].to_numpy()
    np.testing.assert_allclose(kinematics.ForwardKinematics(ur5_dh, nominal).points(MARKER), targets, atol=2e-9)
    np.testing.assert_allclose(robot.robot_points(q), targets, atol=2e-9)


def test_targets_out_of_reach_and_beyond_the_limits_are_listed_with_the_reason(iiwa, rng):
    robot = synthetic_robot(iiwa, rng, zero_offsets_q4=-0.01)  # true angle = command - 0.01 rad
    q0 = commands(iiwa, rng, 3)
    q0[1, 3] = iiwa.upper[3] - 1e-3  # so the compensated command is past joint 4's upper limit
    targets = kinematics.ForwardKinematics(iiwa, q0).points(MARKER)
    targets[0] = [3.0, 0.0, 0.5]  # 3 m away: beyond the iiwa's reach
    out = compensation.compensate(robot, "robot", 50, rng, targets=targets, seeds=q0)
    assert out.loc[0, "status"] == compensation.NOT_REACHED
    assert re.fullmatch(r"nominal model: out of reach: no convergence, closest [0-9.e+]+ mm away", out.loc[0, "reason"])
    assert np.isnan(out.loc[0, "q1"]) and out.loc[2, "status"] == compensation.REACHED
    summary = compensation.not_reached_summary(out)
    assert summary.startswith(f"{(out['status'] != 'reached').sum()} of 3 targets not reached (row")
    beyond = re.fullmatch(r"calibrated model: joint 4 beyond its limits by ([0-9.]+) deg", out.loc[1, "reason"])
    assert beyond and 0.3 < float(beyond.group(1)) < 1.0  # 0.57 deg of zero-offset less the 0.06 deg margin, +-


def test_bounds_follow_the_posterior_spread(iiwa, rng):
    """Tenfold wider posterior rows give tenfold wider bounds (parameters only; the linearised
    model is exact to ~1e-3 at these sizes), and the held zero-offset's tolerance widens the
    robot-frame bound, not the sensor-frame one (the registration holds it there)."""
    q = commands(iiwa, rng, 10)
    narrow = compensation.predict(
        synthetic_robot(iiwa, np.random.default_rng(1), 1e-6), q, "robot", 2000, np.random.default_rng(2)
    )
    wide = compensation.predict(
        synthetic_robot(iiwa, np.random.default_rng(1), 1e-5), q, "robot", 2000, np.random.default_rng(2)
    )
    np.testing.assert_allclose(wide["bound95_mm"] / narrow["bound95_mm"], 10.0, rtol=0.01)
    np.testing.assert_allclose(wide["x"], narrow["x"], atol=1e-12)
    held = synthetic_robot(iiwa, np.random.default_rng(1), 1e-6, held={"zero_offsets.q1": 0.0})
    in_robot = compensation.predict(held, q, "robot", 2000, np.random.default_rng(2))
    radius = np.linalg.norm(in_robot[["x", "y"]].to_numpy(), axis=1)
    # joint 1 at 0.5 deg (1 sigma): the bound is about 1.96 sigma * radius (a rotation about base Z)
    np.testing.assert_allclose(in_robot["bound95_mm"], 1.96 * 0.5 * DEG * radius / MM, rtol=0.15)
    in_sensor = compensation.predict(held, q, "sensor", 2000, np.random.default_rng(2))
    assert np.all(in_sensor["bound95_mm"] < 0.1 * in_robot["bound95_mm"])


def test_a_tcp_leaves_the_marker_effects_out_and_says_so(iiwa, rng):
    robot = synthetic_robot(iiwa, rng, tcp=[0.0, 0.0, 0.2])
    assert "marker_offset" not in robot.blocks and "not applied to a TCP" in robot.notes("sensor")[0]
    q = commands(iiwa, rng, 4)
    poses = robot.predictor(q).flange_poses(robot.calibration.values)
    np.testing.assert_allclose(robot.robot_points(q), poses[:, :3, :3] @ [0.0, 0.0, 0.2] + poses[:, :3, 3], atol=1e-12)


def test_a_tcp_takes_the_priors_split_of_the_marker_offset_and_its_bound_carries_it(iiwa, rng):
    """At a TCP the marker's fitted offset is split between its mount and the flange by the priors
    (`tool_link.ToolSplit`): the position is the flange's pose applied to the tool point plus the
    expected shift, every bound carries what the split leaves, and the notes say it is not determined."""
    tcp = np.array([0.0, 0.0, 0.2])
    split = ToolSplit.of(MARKER, tcp, 1 * MM, 1 * MM, 0.1 * DEG)
    robot = replace(synthetic_robot(iiwa, rng, spread=1e-7, tcp=tcp), tool=split)
    assert "marker_offset" in robot.blocks
    assert any(n.startswith("not determined: where the TCP sits on the flange") for n in robot.notes("robot"))
    q = commands(iiwa, rng, 6)
    values = robot.calibration.values
    poses = robot.predictor(q).flange_poses(values)
    shift = split.mean([values[f"marker_offset.{a}"] for a in "xyz"])
    np.testing.assert_allclose(robot.robot_points(q), poses[:, :3, :3] @ (tcp + shift) + poses[:, :3, 3], atol=1e-12)
    table = compensation.predict(robot, q, "robot", 2000, np.random.default_rng(4))
    # the posterior's own spread is a few um: the bound is the split's, about 2.8 std of a 3-D Gaussian
    expected = 2.8 * np.sqrt(np.trace(split.covariance) / 3.0) / MM
    np.testing.assert_allclose(table["bound95_mm"], expected, rtol=0.15)
    at_marker = compensation.predict(
        synthetic_robot(iiwa, rng, spread=1e-7), q, "robot", 2000, np.random.default_rng(4)
    )
    assert np.all(at_marker["bound95_mm"] < 0.1 * table["bound95_mm"])


def test_at_the_marker_the_last_joints_held_zero_is_in_the_fitted_marker_offset(iiwa, rng):
    """A held last-joint zero-offset is not drawn again at the marker, whose fitted offset holds its
    turn (`carried_by_marker_offset`): the bound is the posterior's own few um, not the 1.7 mm a
    0.5 deg turn of a marker 100 mm off the axis would give; at a TCP there it is drawn, and the
    notes say which."""
    point = np.array([0.1, 0.0, 0.05])
    held = {"zero_offsets.q7": 0.0}
    marker = replace(synthetic_robot(iiwa, np.random.default_rng(1), 1e-7, held=held), point=point)
    tcp = replace(marker, at_marker=False)
    q = commands(iiwa, rng, 8)
    at_marker = compensation.predict(marker, q, "robot", 2000, np.random.default_rng(2))
    at_tcp = compensation.predict(tcp, q, "robot", 2000, np.random.default_rng(2))
    assert marker.held_drawn("robot") == [] and tcp.held_drawn("robot") == ["zero_offsets.q7"]
    assert np.all(at_marker["bound95_mm"] < 0.01)
    # a turn about the last axis at 0.5 deg (1 sigma), 100 mm off it: about 1.96 sigma * 100 mm
    np.testing.assert_allclose(at_tcp["bound95_mm"], 1.96 * 0.5 * DEG * 0.1 / MM, rtol=0.15)
    assert any("q7, held at the controller's mark, is carried at the marker" in n for n in marker.notes("robot"))
    assert not any("carried at the marker" in n for n in tcp.notes("robot"))


# --------------------------------------------------------------------------- bad input


def test_bad_commands_name_the_file_column_and_rows(iiwa):
    table = pd.DataFrame({f"q{j + 1}": [0.1, 0.2, 0.3] for j in range(7)})
    with pytest.raises(InputError, match=r"c.csv: q6, q7: missing joint column\(s\) \(got: q1"):
        compensation.joint_commands(table.drop(columns=["q6", "q7"]), iiwa, "c.csv")
    bad = table.astype(object)
    bad.loc[1, "q3"] = "abc"
    bad.loc[2, "q3"] = np.nan
    with pytest.raises(InputError, match=r"c.csv: q3: not a finite number \(rows 1, 2\)"):
        compensation.joint_commands(bad, iiwa, "c.csv")
    far = table.copy()
    far.loc[2, "q4"] = 120.0  # degrees given for radians
    with pytest.raises(
        InputError, match=r"c.csv: q4: beyond the joint limits .* rad \(commands are in rad\) \(row 2\)"
    ):
        compensation.joint_commands(far, iiwa, "c.csv")
    with pytest.raises(InputError, match="c.csv: no rows"):
        compensation.joint_commands(table.iloc[:0], iiwa, "c.csv")
    assert compensation.joint_commands(pd.DataFrame({"x": [1.0]}), iiwa, "c.csv", required=False) is None


def test_the_command_line_refuses_bad_input_and_writes_nothing(tmp_path, capsys):
    campaign = str(REPO / "data" / "raw" / "kuka-twin")
    out = tmp_path / "out.csv"
    common = ["--campaign", campaign, "--sensor", "laser_tracker", "--out", str(out)]
    assert cli(["predict", *common, "--results", str(tmp_path / "nowhere"), "--commands", "c.csv"]) == 2
    assert "nowhere/kuka-twin/laser_tracker: no results of this campaign and sensor" in capsys.readouterr().err
    (tmp_path / "results" / "kuka-twin" / "laser_tracker").mkdir(parents=True)
    assert cli(["predict", *common, "--results", str(tmp_path / "results"), "--commands", "c.csv"]) == 2
    assert "laser_tracker/registration.json: not written: run `snakemake -j2` on the campaign first" in (
        capsys.readouterr().err
    )
    assert (
        cli(
            [
                "compensate",
                "--campaign",
                campaign,
                "--sensor",
                "camera",
                "--results",
                str(tmp_path / "results"),
                "--targets",
                "t.csv",
            ]
        )
        == 2
    )
    assert "no results of this campaign and sensor" in capsys.readouterr().err
    for bad in (["--draws", "0"], ["--model", "full"]):
        with pytest.raises(SystemExit) as exited:
            cli(["predict", *common, "--commands", "c.csv", *bad])
        assert exited.value.code == 2
    err = capsys.readouterr().err
    assert "--draws: must be at least 1, got 0" in err and "--model: invalid choice: 'full'" in err
    assert not out.exists()


# --------------------------------------------------------------------------- closed loop on the simulator


@pytest.fixture(scope="module")
def twin_fitted(tmp_path_factory):
    """The twin's laser-tracker loop closure, fitted once (`test_workspace.fitted`) in the set-up of
    the first test that needs it, not in its call (a test's call is held to the 60 s limit)."""
    return fitted("kuka-twin", "laser_tracker", tmp_path_factory)


def twin(model: str, tmp_path_factory):
    """The twin's laser-tracker calibration (fitted in-process, shared with test_workspace) and
    its true robot and sensor. The twin drifts: a calibration's zero-offsets are those of its drift
    block's time origin, the first measurement, so the true robot is taken then (`at_start`)."""
    campaign, laplace, report, samples = fitted("kuka-twin", "laser_tracker", tmp_path_factory)
    results = {
        "registration": fit.registration_stage(campaign, "laser_tracker"),
        "laplace": laplace,
        "summary": mode_summary(laplace),
        "paper_samples": None,
        "loop": report,
        "loop_samples": samples,
        "gp": None,
    }
    truth = files.read_json(REPO / "data" / "truth" / "kuka-twin.json")
    sensor = sensor_from_truth(truth, "laser_tracker", campaign.sensors["laser_tracker"].marker)
    return (
        campaign,
        compensation.calibrated_robot(campaign, "laser_tracker", model, results),
        robot_from_truth(truth),
        sensor,
    )


@pytest.mark.usefixtures("twin_fitted")
def test_a_declared_model_error_is_in_every_bound(tmp_path_factory):
    """A loop that is not closed declares its residual per axis, d (`LoopReport.declared_model_error`),
    and predict's bound at a command then holds a draw of N(0, d^2 I3) besides the posterior's
    own spread: with d far above that spread, the bound is d times the 95th percentile of a chi
    with 3 degrees of freedom, within the Monte Carlo error of a quantile of 4,000 draws; with
    d = 0 it is the posterior's alone, far below."""
    campaign, robot, _, _ = twin("loop", tmp_path_factory)
    q = campaign.sensors["laser_tracker"].q("validation")[:20]
    declared = 1.0 * MM
    # the sensor frame: the registration takes up what the robot frame leaves to the held joints' tolerance
    own = compensation.predict(replace(robot, declared=0.0), q, "sensor", 4000, np.random.default_rng(1))
    wide = compensation.predict(replace(robot, declared=declared), q, "sensor", 4000, np.random.default_rng(1))
    assert (own["bound95_mm"] < 0.1 * declared / MM).all()
    chi = stats.chi(3)
    expected = declared * chi.ppf(0.95) / MM
    monte_carlo = declared / MM * np.sqrt(0.95 * 0.05 / 4000) / chi.pdf(chi.ppf(0.95))
    np.testing.assert_allclose(wide["bound95_mm"], expected, atol=4 * monte_carlo + own["bound95_mm"].max())


@pytest.mark.usefixtures("twin_fitted")
def test_a_declared_field_moves_one_arms_commands_together_and_keeps_each_commands_spread(tmp_path_factory):
    """The declared model error as a field (`LoopReport.declared_field`) smooth over the joints:
    drawn `jointly`, every command of one draw moves together, as one arm's field does, where drawn
    per command (predict's bounds) they move apart; each command's spread is the declared error's
    either way, so a per-command bound is the same."""
    campaign, robot, _, _ = twin("loop", tmp_path_factory)
    q = campaign.sensors["laser_tracker"].q("validation")[:20]
    declared = 1.0 * MM
    smooth = Hyperparameters(np.full(7, 1e3), declared, 0.0)
    robot = replace(robot, declared=declared, declared_field=smooth)
    mean = robot.in_frame(robot.robot_points(q), "sensor")
    per_command = robot.draw_points(q, "sensor", 2000, np.random.default_rng(1))[0] - mean
    jointly = robot.draw_points(q, "sensor", 2000, np.random.default_rng(1), jointly=True)[0] - mean
    for draws in (per_command, jointly):
        np.testing.assert_allclose(draws.std(axis=0), declared, rtol=0.1)
    assert (jointly - jointly.mean(axis=1, keepdims=True)).std() < 0.1 * declared
    assert (per_command - per_command.mean(axis=1, keepdims=True)).std() > 0.9 * declared


def closed_loop(frame: str, tmp_path_factory):
    """The twin's validation configurations as a nominal program, compensated in `frame` by the
    loop-closed model and sent to the simulator's true robot: (table, true miss of the nominal
    commands, true miss of the compensated ones) in m, for the commands the compensation reached.
    A command within a degree of a joint limit may have no compensated twin inside the limits:
    such a row must say so, and only such a row may."""
    campaign, robot, true_robot, sensor = twin("loop", tmp_path_factory)
    q0 = campaign.sensors["laser_tracker"].q("validation")
    out = compensation.compensate(robot, frame, 1000, np.random.default_rng(5), commands=q0)
    reached = (out["status"] == compensation.REACHED).to_numpy()
    chain = campaign.chain
    at_a_limit = np.min(np.minimum(q0 - chain.lower, chain.upper - q0), axis=1) < np.radians(1.0)
    assert reached.mean() > 0.95 and not np.any(~reached & ~at_a_limit)
    assert out.loc[~reached, "reason"].str.contains("beyond its limits").all()
    out, q0 = out[reached], q0[reached]
    q = out[[f"q{j + 1}" for j in range(7)]].to_numpy()
    where = true_sensor_positions if frame == "sensor" else true_marker_positions
    targets = out[["target_x", "target_y", "target_z"]].to_numpy()
    return (
        out,
        np.linalg.norm(where(campaign.chain, true_robot, sensor, q0, at_start(q0)) - targets, axis=1),
        np.linalg.norm(where(campaign.chain, true_robot, sensor, q, at_start(q)) - targets, axis=1),
    )


@pytest.mark.usefixtures("twin_fitted")
def test_compensated_commands_reach_the_twins_targets_on_its_true_robot(tmp_path_factory):
    """Targets where the nominal cell (nominal kinematics, the campaign's initial registration)
    puts them in the laser tracker's frame: the nominal commands miss by millimetres, the
    compensated ones reach them to within the tracker's noise (10 um per axis)."""
    out, nominal_miss, miss = closed_loop("sensor", tmp_path_factory)
    noise = np.sqrt(3) * 10e-6  # RMS length of the tracker's noise vector
    assert np.sqrt(np.mean(nominal_miss**2)) > 1e-3
    assert np.sqrt(np.mean(miss**2)) < noise
    np.testing.assert_allclose(out["nominal_error_mm"] * MM, nominal_miss, rtol=0.05, atol=2 * noise)


@pytest.mark.usefixtures("twin_fitted")
def test_in_the_robot_frame_the_unseen_joint_1_zero_is_in_the_bound(tmp_path_factory):
    """In the robot frame the compensated commands miss by joint 1's true zero-offset (0.48 deg,
    which no sensor sees: the registration absorbs it) times the radius, and the 95 % bounds,
    which draw it at the controller marks' tolerance, cover every row."""
    out, _, miss = closed_loop("robot", tmp_path_factory)
    assert np.sqrt(np.mean(miss**2)) > 1e-3
    assert np.all(miss <= out["bound95_mm"].to_numpy() * MM)


@pytest.mark.usefixtures("twin_fitted")
def test_the_posterior_holds_the_true_errors_of_the_compensated_commands(tmp_path_factory):
    """One calibration is one realization: the true errors at all commands come from one parameter
    error, so the share of rows inside their own 95 % bound is not 95 % by promise (88 % here). What
    the posterior does promise, and this checks, is that the true positions are a plausible draw
    from it: the truth's total squared deviation over every command ranks inside the central 95 % of
    the draws', and in the draws' leading principal directions the truth's whitened coordinates
    have a chi-square below its 97.5th percentile. Not above its 2.5th: those directions are the ones
    the link-geometry priors (1 mm, 0.1 deg per transform) spread, and the twin's true link errors
    are far smaller than the priors (rotations about 5e-5 rad), so there the truth sits nearer the
    centre than a draw from the prior would (chi-square 5.7 of 20 with a sampler that follows the
    posterior's valley to its ends; emcee, which stopped short of them, had left it inside)."""
    campaign, robot, true_robot, sensor = twin("loop", tmp_path_factory)
    q0 = campaign.sensors["laser_tracker"].q("validation")
    out = compensation.compensate(robot, "sensor", 200, np.random.default_rng(5), commands=q0)
    q = out[[f"q{j + 1}" for j in range(7)]].to_numpy()
    draws, _ = robot.draw_points(q, "sensor", 2000, np.random.default_rng(7))
    centre = draws.mean(axis=0)
    error = true_sensor_positions(campaign.chain, true_robot, sensor, q, at_start(q)) - centre
    spread = draws - centre
    rank = np.mean(np.sum(spread**2, axis=(1, 2)) < np.sum(error**2))
    assert 0.025 < rank < 0.975
    _, singular, directions = np.linalg.svd(spread.reshape(len(draws), -1), full_matrices=False)
    leading = 20
    whitened = directions[:leading] @ error.ravel() / (singular[:leading] / np.sqrt(len(draws)))
    assert np.sum(whitened**2) < stats.chi2(leading).ppf(0.975)


# --------------------------------------------------------------------------- the command line, end to end


@pytest.fixture(scope="module")
def twin_results(tmp_path_factory):
    """A results folder as `snakemake -j2` writes it for the twin's laser tracker (the loop closure
    fitted in-process; the paper model without MCMC samples)."""
    campaign, laplace, report, samples = fitted("kuka-twin", "laser_tracker", tmp_path_factory)
    root = tmp_path_factory.mktemp("results")
    folder = root / "kuka-twin" / "laser_tracker"
    files.write_json(folder / layout.REGISTRATION, fit.registration_stage(campaign, "laser_tracker").report())
    files.write_json(folder / layout.LAPLACE, laplace_content("kuka-twin", "laser_tracker"))
    files.write_csv(folder / layout.SUMMARY, mode_summary(laplace).reset_index())
    files.write_parquet(folder / layout.DEFAULT_SAMPLES, pd.DataFrame())
    report.write(folder / layout.LOOP_CLOSURE)
    files.write_parquet(folder / layout.LOOP_SAMPLES, samples)
    files.write_parquet(folder / layout.LOOP_GP, pd.DataFrame())
    digests = {"kuka-twin": folders.campaign_digests(REPO / "data" / "raw" / "kuka-twin", REPO)}
    files.write_json(root / layout.AUDIT, audit.audit_record(digests, {}, {}))
    return root, campaign


def test_predict_and_compensate_from_the_command_line(twin_results, tmp_path, capsys, monkeypatch):
    root, campaign = twin_results
    monkeypatch.chdir(REPO)  # the campaign's URDF path is the repository's
    q = campaign.sensors["laser_tracker"].q("validation")[:6]
    program = tmp_path / "program.csv"
    files.write_csv(program, pd.DataFrame(q, columns=[f"q{j + 1}" for j in range(7)]))
    common = ["--campaign", "data/raw/kuka-twin", "--sensor", "laser_tracker", "--results", str(root), "--draws", "300"]
    assert cli(["predict", *common, "--commands", str(program), "--out", str(tmp_path / "p.csv")]) == 0
    predicted = files.read_csv(tmp_path / "p.csv")
    assert len(predicted) == 6 and predicted["bound95_mm"].notna().all()
    assert "the zero-offset of q1, which these data do not see" in capsys.readouterr().err
    assert (
        cli(["compensate", *common, "--frame", "sensor", "--targets", str(program), "--out", str(tmp_path / "c.csv")])
        == 0
    )
    compensated = files.read_csv(tmp_path / "c.csv")
    assert (compensated["status"] == compensation.REACHED).all() and (compensated["nominal_error_mm"] > 0.5).all()
    # targets: the compensated ones' targets, one moved 3 m away; exit 3, every row written
    targets = compensated[["target_x", "target_y", "target_z"]].rename(columns=lambda c: c[-1])
    targets.loc[4, "x"] += 3.0
    files.write_csv(tmp_path / "t.csv", targets)
    assert (
        cli(
            [
                "compensate",
                *common,
                "--frame",
                "sensor",
                "--targets",
                str(tmp_path / "t.csv"),
                "--out",
                str(tmp_path / "c2.csv"),
            ]
        )
        == 3
    )
    assert "1 of 6 targets not reached (row 4): see the column reason" in capsys.readouterr().err
    again = files.read_csv(tmp_path / "c2.csv")
    assert len(again) == 6 and again.loc[4, "reason"].startswith("nominal model: out of reach")
    # from targets alone (seeded at the nearest optimization configuration) the other rows are reached
    reached = again.drop(index=4)
    assert (reached["status"] == compensation.REACHED).all() and (reached["error_mm"] < 1e-6).all()
    files.write_csv(tmp_path / "bad.csv", pd.DataFrame({"a": [1.0], "b": [2.0]}))
    assert cli(["compensate", *common, "--targets", str(tmp_path / "bad.csv"), "--out", str(tmp_path / "c3.csv")]) == 2
    assert (
        "bad.csv: x, y, z or q1..q7: neither target positions nor joint commands (got: a, b)" in capsys.readouterr().err
    )
    assert not (tmp_path / "c3.csv").exists()


def test_a_campaign_changed_since_its_results_were_made_is_refused(twin_results, tmp_path, capsys, monkeypatch):
    """The results are the twin's as it was when they were made (its audit.json records its content
    hash): a copy of the twin elsewhere is the same campaign, the copy with its laser tracker's
    marker moved by 1 cm is not, and predict and compensate refuse it naming the audit, the
    campaign, both hashes and the file that differs; nothing is written. Results without an audit,
    or whose audit does not know the campaign, are refused too."""
    root, _ = twin_results
    monkeypatch.chdir(REPO)  # the campaign's URDF path is the repository's
    copy = tmp_path / "kuka-twin"
    shutil.copytree(REPO / "data" / "raw" / "kuka-twin", copy)
    check_made_from(root, copy, REPO)  # renaming the folder's path changes nothing
    made_from = files.read_json(root / layout.AUDIT)["campaigns"]["kuka-twin"]["content_sha256"]
    text = (copy / "campaign.yaml").read_text()
    (copy / "campaign.yaml").write_text(text.replace("marker: [-0.1, 0.0, 0.02]", "marker: [-0.1, 0.0, 0.03]"))
    now = audit.folder_digest(folders.campaign_digests(copy, REPO))
    assert now != made_from
    files.write_csv(tmp_path / "q.csv", pd.DataFrame(np.zeros((1, 7)), columns=[f"q{j + 1}" for j in range(7)]))
    common = ["--campaign", str(copy), "--sensor", "laser_tracker", "--results", str(root)]
    for command, given in (("predict", "--commands"), ("compensate", "--targets")):
        out = tmp_path / f"{command}.csv"
        assert cli([command, *common, given, str(tmp_path / "q.csv"), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"remaster {command}: error: {root / layout.AUDIT}: campaigns/kuka-twin/content_sha256: " in err
        assert f"the campaign {copy} has changed since these results were made from it" in err
        assert f"its content SHA-256 is {now}, the results were made from {made_from}" in err
        assert "(files that differ: campaign.yaml)" in err
        assert not out.exists()
    # the next configurations of the campaign are planned from its results under the same rule
    plan = ["plan", "--from-results", str(root / "kuka-twin" / "laser_tracker"), "--campaign", str(copy)]
    assert cli([*plan, "--budget", "2", "--out", str(tmp_path / "next.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"remaster plan: error: {root / layout.AUDIT}: campaigns/kuka-twin/content_sha256: ")
    assert f"its content SHA-256 is {now}, the results were made from {made_from}" in err
    assert not (tmp_path / "next.csv").exists()
    with pytest.raises(InputError, match=r"audit.json: not written: `snakemake -j2` writes it"):
        check_made_from(tmp_path / "no-run", copy, REPO)
    files.write_json(tmp_path / "other-run" / layout.AUDIT, audit.audit_record({"tiny": {}}, {}, {}))
    with pytest.raises(
        InputError, match=r"other-run/audit.json: campaigns/kuka-twin: the run that wrote these results"
    ):
        check_made_from(tmp_path / "other-run", copy, REPO)


def test_a_result_changed_since_the_run_recorded_it_is_refused(tmp_path):
    """The audit records the SHA-256 of every result file: one truncated afterwards (its time stamp
    kept, so Snakemake sees nothing) is named when predict, compensate or plan check the results."""
    results = tmp_path / "results"
    report = results / "kuka-twin" / "laser_tracker" / layout.LOOP_CLOSURE
    files.write_json(report, {"effects_added": []})
    digests = {"kuka-twin": folders.campaign_digests(REPO / "data" / "raw" / "kuka-twin", REPO)}
    made = f"{results}/kuka-twin/laser_tracker/{layout.LOOP_CLOSURE}"
    recorded = {"kuka-twin": {made: audit.sha256(report.read_bytes())}}
    files.write_json(results / layout.AUDIT, audit.audit_record(digests, recorded, {"results_dir": str(results)}))
    check_made_from(results, REPO / "data" / "raw" / "kuka-twin", REPO)
    stamp = report.stat().st_mtime_ns
    report.write_bytes(report.read_bytes()[:-3])
    os.utime(report, ns=(stamp, stamp))
    with pytest.raises(
        InputError, match=r"campaigns/kuka-twin/results: kuka-twin/laser_tracker/loop_closure.json: changed"
    ):
        check_made_from(results, REPO / "data" / "raw" / "kuka-twin", REPO)


def test_reports_whose_results_failed_are_stale(tmp_path):
    """After a failed job: a certificate with a result it reads missing or newer than it is stale,
    and then the run's report and audit; a campaign whose results are all older is not."""
    for campaign in ("good", "failed"):
        for name in (*results_module.SENSOR_RESULTS_READ, layout.ACCEPTANCE):
            files.write_json(tmp_path / campaign / "laser_tracker" / name, {})
    past = time.time_ns() - 10**10
    for path in tmp_path.rglob("*.json"):
        os.utime(path, ns=(past, past))
    for campaign in ("good", "failed"):
        for name in results_module.CAMPAIGN_REPORTS:
            (tmp_path / campaign / name).write_text("made")
    (tmp_path / "report.html").write_text("made")
    sensors = {"good": ["laser_tracker"], "failed": ["laser_tracker"]}
    assert results_module.stale_reports(tmp_path, sensors) == []
    (tmp_path / "failed" / "laser_tracker" / layout.LOOP_CLOSURE).unlink()
    stale = results_module.stale_reports(tmp_path, sensors)
    assert sorted(p.relative_to(tmp_path).as_posix() for p in stale) == [
        "failed/certificate.json",
        "failed/certificate.md",
        "report.html",
    ]
    files.write_json(tmp_path / "failed" / "laser_tracker" / layout.LOOP_CLOSURE, {})  # newer than the certificate
    assert len(results_module.stale_reports(tmp_path, sensors)) == 3


def test_a_command_beyond_the_data_is_not_determined_naming_the_joint_the_data_held(iiwa):
    """Measured configurations with joint 3 held at 0: a command near them is determined; one that
    turns joint 3 is not, and says which joint; one far in the others' joints says how far; a
    command not reached has no distance and is not determined."""
    rng = np.random.default_rng(4)
    measured = rng.uniform(-1.0, 1.0, (60, 7))
    measured[:, 2] = 0.0
    near = Nearness.of(iiwa, measured, np.array([0.0, 0.0, 0.05]))
    assert near.held_joints() == {2: 0.0}
    commands = np.vstack([measured[:2], measured[:1] + [0, 0, 0.5, 0, 0, 0, 0], [[2.5, 1.8, 0, -1.9, 2.4, 1.9, 2.6]]])
    commands = np.vstack([commands, np.full((1, 7), np.nan)])
    table = compensation.with_nearness(pd.DataFrame(index=range(5)), near, commands)
    assert table["determined"].tolist() == [True, True, False, False, False]
    why = table["not_determined_why"].tolist()
    assert why[:2] == ["", ""]
    assert why[2].startswith("not determined: q3 held at 0 deg in the data, here 28.6") and "the priors'" in why[2]
    assert re.match(
        r"not determined: [\d.e+]+ mm from the measured configurations \(their spacing [\d.e+]+ mm\)", why[3]
    )
    assert why[4] == "not determined: no configuration to compare (not reached)"
    assert table["near_data"].tolist()[:2] == [True, True] and not table["near_data"].iloc[3]


def test_one_turn_away_a_joint_scale_model_is_not_determined_and_says_why(ur5_dh):
    """Commands at the measured configurations with joint 1 read one turn away (as a UR reaches a
    pose again): the zero-offset model puts the marker where it did and they are as determined
    as before; a model with a joint scale on joint 1 corrects 2 pi s_1 more there, which nothing
    measured: `predict` says they are not determined, naming joint 1, the turn and the joint scale."""
    rng = np.random.default_rng(6)
    measured = rng.uniform(-1.5, 1.5, (80, 6))
    offsets = {f"zero_offsets.q{j + 1}": rng.normal(0.0, 0.3 * DEG) for j in range(6)}
    scale = 3e-4
    models = {
        "paper": prediction.Calibration("paper", offsets),
        "loop": prediction.Calibration("loop", {**offsets, "joint_scale.q1": scale}, ("joint_scale",)),
    }
    q = measured[:4]
    turned = q + [2 * np.pi, 0, 0, 0, 0, 0]
    tables = {}
    for name, calibration in models.items():
        robot = compensation.CalibratedRobot(
            ur5_dh,
            calibration,
            MARKER,
            True,
            {},
            np.eye(4),
            pd.DataFrame(),
            {},
            0.5 * DEG,
            near=Nearness.of(ur5_dh, measured, MARKER, calibration.linear_joints),
        )
        tables[name] = [compensation.predict(robot, x, "robot", 10, np.random.default_rng(0)) for x in (q, turned)]
    at, away = tables["paper"]
    xyz = ["x", "y", "z"]
    np.testing.assert_allclose(away[xyz].to_numpy(), at[xyz].to_numpy(), atol=1e-12)
    assert at["determined"].all() and away["determined"].all()
    at, away = tables["loop"]
    moved = np.linalg.norm(away[xyz].to_numpy() - at[xyz].to_numpy(), axis=1)
    reach = np.linalg.norm(at[["x", "y"]].to_numpy(), axis=1)  # from joint 1's axis, the base's z
    np.testing.assert_allclose(moved, 2 * reach * np.sin(np.pi * scale), rtol=1e-9)  # joint 1 turned 2 pi s further
    assert at["determined"].all() and not away["determined"].any() and not away["near_data"].any()
    for why, angle in zip(away["not_determined_why"], np.degrees(turned[:, 0])):
        assert why.startswith(f"not determined: q1 reads {angle:.4g} deg here, one turn from about")
        assert "near on the circle only" in why and "joint scale" in why
