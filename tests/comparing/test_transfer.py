"""Transfer between campaigns of one robot and the comparison of calibrations by prediction, on
small synthetic campaigns with known answers."""

from __future__ import annotations

import dataclasses

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from remaster import spatial
from remaster.calibration import prediction
from remaster.campaigns.campaign import SensorData
from remaster.comparing import predictions, transfer
from remaster.inference.metrics import random_configurations
from remaster.inference.parameter_blocks import link_labels
from remaster.inference.readings import ModelSettings
from remaster.reporting import figures_comparison
from remaster.robot import registration
from remaster.robot.ik import SRSInverseKinematics
from remaster.robot.kinematics import ForwardKinematics
from remaster.units import MM

MARKER = np.array([-0.1, 0.0, 0.02])
ROBOT = "serial:test-arm"
OFFSETS = np.array([0.0, 0.004, -0.003, 0.002, 0.005, -0.002, 0.006])  # rad
NOISE = 1e-5  # m per axis


def sensor_table(q: np.ndarray, xyz: np.ndarray, n_optimization: int) -> SensorData:
    """A laser tracker's table of readings q (n, N) and positions xyz (n, 3): the first
    n_optimization rows the optimization set, the others the validation set."""
    table = pd.DataFrame(q, columns=[f"q{j + 1}" for j in range(q.shape[1])])
    table.insert(0, "set", ["optimization"] * n_optimization + ["validation"] * (len(q) - n_optimization))
    table["pose"] = np.arange(len(q)) // 2
    table["solution"] = np.arange(len(q)) % 2
    table[["x", "y", "z"]] = xyz
    return SensorData("laser_tracker", "laser_tracker", MARKER, NOISE, table)


def sensor_from_robot() -> np.ndarray:
    """A sensor standing somewhere: rotated about an oblique axis and 2 m away."""
    transform = np.eye(4)
    transform[:3, :3] = spatial.euler_zyx_to_matrix(0.7, -0.2, 0.3)
    transform[:3, 3] = [2.0, -0.5, 0.3]
    return transform


def entry(chain, name: str, date: str, sensor: SensorData, models: dict, excluded=()) -> prediction.Calibrated:
    return prediction.Calibrated(name, date, ROBOT, sensor, chain, models, tuple(excluded))


def paper(offsets, draws=None) -> prediction.Calibration:
    return prediction.Calibration(
        "paper", {f"zero_offsets.q{j + 1}": float(v) for j, v in enumerate(offsets)}, draws=draws
    )


@pytest.fixture(scope="module")
def noisy(iiwa):
    """A campaign of the paper's model with noise, one unseen and one flagged optimization row."""
    rng = np.random.default_rng(5)
    q = random_configurations(iiwa, 40, rng) * 0.6
    robot = ForwardKinematics(iiwa, q).points(MARKER, OFFSETS)
    xyz = spatial.transform_points(sensor_from_robot(), robot) + NOISE * rng.standard_normal(robot.shape)
    xyz[3] = np.nan  # marker not seen
    xyz[7] += 0.01  # a gross error the fit flagged
    return sensor_table(q, xyz, 24)


def test_own_paper_model_on_itself_is_a_direct_validation(iiwa, noisy):
    """(a) X = Y, paper model: flange poses from FK with the zero-offsets, the registration and the
    marker fitted on the optimization rows used (the default marker prior), errors on the validation
    rows, computed directly."""
    estimate = OFFSETS + 1e-4  # a posterior mean a little off the truth
    errors = transfer.transfer_errors(paper(estimate), entry(iiwa, "x", "2020-01-01", noisy, {}, excluded=[7]))
    opt = np.setdiff1d(np.arange(24), [3, 7])
    val = np.arange(24, 40)
    q, xyz = noisy.q(), noisy.positions()
    flange = ForwardKinematics(iiwa, q + estimate).flange_poses()
    np.testing.assert_allclose(
        flange[:, :3, :3] @ MARKER + flange[:, :3, 3], ForwardKinematics(iiwa, q).points(MARKER, estimate), atol=1e-12
    )
    fitted, marker = transfer.refitted_set_up(flange[opt], MARKER, xyz[opt], NOISE, prediction.DEFAULT_MARKER_STD)
    direct = np.linalg.norm(
        xyz[val] - spatial.transform_points(fitted, flange[val, :3, :3] @ marker + flange[val, :3, 3]), axis=1
    )
    np.testing.assert_allclose(errors, direct, rtol=1e-9, atol=1e-12)
    assert np.linalg.norm(marker - MARKER) < 5 * NOISE  # the marker was right: the refit leaves it near
    table = transfer.transfer_table([entry(iiwa, "x", "2020-01-01", noisy, {"paper": paper(estimate)}, [7])])
    assert list(table.columns) == transfer.TRANSFER_COLUMNS
    row = table.iloc[0]
    assert row["count"] == 16 and row["rmse_mm"] == pytest.approx(np.sqrt(np.mean(direct**2)) / MM)
    assert row["p95_mm"] == pytest.approx(np.quantile(direct, 0.95) / MM)


def loop_values(chain) -> dict[str, float]:
    """A loop model's values: zero-offsets, link geometry, joint compliance and a marker offset, plus
    set-up parameters that must not be transferred."""
    values = {f"zero_offsets.q{j + 1}": float(v) for j, v in enumerate(OFFSETS)}
    for i, (_, column, name) in enumerate(link_labels(chain)):
        values[name] = (3e-4 if column == 0 else 2e-4) * (-1) ** i
    values.update(
        {
            "joint_compliance.q2": 3e-5,
            "joint_compliance.q4": 2e-5,
            "marker_offset.x": 4e-4,
            "marker_offset.z": -3e-4,
            "sensor_scale.s": 0.5,
            "registration.x": 1.0,
            "drift.q2": 1.0,
        }
    )
    return values


def test_transfer_of_exact_predictions_is_zero(iiwa):
    """(b) Y's measurements are X's loop model's exact predictions (no noise), seen from another
    sensor position: the transfer RMSE is ~0, the nominal's is not."""
    rng = np.random.default_rng(6)
    loop = prediction.Calibration(
        "loop",
        loop_values(iiwa),
        ("link_geometry", "joint_compliance", "marker_offset"),
        ModelSettings(payload_mass=2.0, payload_com=(0.0, 0.0, 0.03)),
    )
    q = random_configurations(iiwa, 30, rng) * 0.6
    robot = prediction.robot_points(iiwa, q, MARKER, loop.values, loop.blocks, loop.settings)
    target = sensor_table(q, spatial.transform_points(sensor_from_robot(), robot), 18)
    x = entry(
        iiwa,
        "x",
        "2020-01-01",
        sensor_table(q, np.zeros((30, 3)), 18),
        {"nominal": prediction.Calibration("nominal"), "loop": loop},
    )
    y = entry(iiwa, "y", "2021-01-01", target, {"nominal": prediction.Calibration("nominal")})
    table = transfer.transfer_table([y, x]).set_index(["model", "calibrated_on", "evaluated_on"])
    assert table.loc[("loop", "x", "y"), "rmse_mm"] < 1e-6
    assert table.loc[("nominal", "x", "y"), "rmse_mm"] > 0.5  # 0.1-0.4 deg off: millimetres
    assert table.loc[("nominal", "x", "y"), "count"] == 12
    assert ("loop", "y", "x") not in table.index  # y has no loop model
    assert table.reset_index()["calibrated_on"].iloc[0] == "x"  # date order


def test_the_set_up_is_fitted_against_the_scatter_it_leaves(iiwa, noisy):
    """The scatter the marker is fitted against settles at the larger of the stated noise and the
    fit's own residual: a fixed point of `kabsch_with_marker` (a model error of 0.3 mm from
    zero-offsets 0.02 deg off keeps a weakly turned marker near the one carried; the stated noise
    alone would let it take the model error up)."""
    q, xyz = noisy.q(), noisy.positions()
    rows = np.setdiff1d(np.arange(24), [3, 7])
    flange = ForwardKinematics(iiwa, q[rows] + OFFSETS + 3e-4).flange_poses()
    fitted, marker = transfer.refitted_set_up(flange, MARKER, xyz[rows], NOISE, 1e-3)
    points = flange[:, :3, :3] @ marker + flange[:, :3, 3]
    scatter = np.sqrt(np.mean((xyz[rows] - spatial.transform_points(fitted, points)) ** 2))
    assert scatter > 10 * NOISE  # the model error, not the noise
    again = registration.kabsch_with_marker(flange, MARKER, xyz[rows], scatter, 1e-3)
    np.testing.assert_allclose(again[1], marker, atol=0.02 * np.linalg.norm(marker - MARKER) + 1e-9)
    _, free = registration.kabsch_with_marker(flange, MARKER, xyz[rows], NOISE, 1e-3)
    assert np.linalg.norm(marker - MARKER) < np.linalg.norm(free - MARKER)


def test_a_remounted_marker_is_refitted_not_carried(iiwa):
    """Y's marker sits where the nominal says, X's loop model found it 0.5 mm away (X's own mount):
    the transfer refits the marker with Y's registration, so X's kinematics predict Y exactly."""
    rng = np.random.default_rng(8)
    values = loop_values(iiwa)
    loop = prediction.Calibration("loop", values, ("link_geometry", "marker_offset"))
    q = random_configurations(iiwa, 30, rng) * 0.6
    unmoved = {k: v for k, v in values.items() if not k.startswith("marker_offset")}
    robot = prediction.robot_points(iiwa, q, MARKER, unmoved, loop.blocks)
    y = entry(iiwa, "y", "2021-01-01", sensor_table(q, spatial.transform_points(sensor_from_robot(), robot), 18), {})
    carried = np.linalg.norm(robot - prediction.robot_points(iiwa, q, MARKER, values, loop.blocks), axis=1)
    assert carried.min() > 4e-4  # what carrying X's marker would cost
    assert np.sqrt(np.mean(transfer.transfer_errors(loop, y) ** 2)) < 1e-8


def draws_around(calibration: prediction.Calibration, std: float, count: int, rng) -> pd.DataFrame:
    names = [n for n in calibration.values if n.startswith("zero_offsets.") and n != "zero_offsets.q1"]
    return pd.DataFrame({n: calibration.values[n] + std * rng.standard_normal(count) for n in names})


def test_prediction_of_a_model_against_itself_and_against_a_rotated_joint(iiwa):
    """(c) The same model: no change, not flagged. Joint 2's zero-offset shifted by d: each point
    moves by r d, r its distance from joint 2's axis."""
    rng = np.random.default_rng(7)
    q = random_configurations(iiwa, 300, rng)
    a = paper(OFFSETS)
    a = prediction.Calibration("paper", a.values, draws=draws_around(a, 1e-6, 400, rng))
    same = predictions.compare_predictions(iiwa, q, MARKER, a, a, 50, np.random.default_rng(1))
    assert same["mean_mm"] == 0.0 and same["p95_mm"] == 0.0 and not same["flagged"]
    assert same["status"] == "compared" and same["draw_pairs"] == 50 and same["null_p95_of_aligned_mean_mm"] > 0

    d = 2e-4  # rad
    b = prediction.Calibration(
        "paper",
        {**a.values, "zero_offsets.q2": a.values["zero_offsets.q2"] + d},
        draws=a.draws.assign(**{"zero_offsets.q2": a.draws["zero_offsets.q2"] + d}),
    )
    moved = predictions.compare_predictions(iiwa, q, MARKER, a, b, 50, np.random.default_rng(1))
    fk = ForwardKinematics(iiwa, q)
    frames = fk.joint_frames(OFFSETS)[:, 1]
    axis = np.einsum("nij,j->ni", frames[:, :3, :3], iiwa.joint_axes[1])
    r = np.linalg.norm(np.cross(axis, fk.points(MARKER, OFFSETS) - frames[:, :3, 3]), axis=1)
    assert moved["mean_mm"] == pytest.approx(d * r.mean() / MM, rel=1e-3)
    assert moved["p95_mm"] == pytest.approx(d * np.quantile(r, 0.95) / MM, rel=1e-3)
    assert moved["flagged"] and moved["null_p95_of_aligned_mean_mm"] < 0.1 * moved["mean_mm"]
    # the null does not see the shift: draws are deviations from each model's own mean
    assert moved["null_p95_of_aligned_mean_mm"] == pytest.approx(same["null_p95_of_aligned_mean_mm"], rel=0.5)
    unsampled = predictions.compare_predictions(iiwa, q, MARKER, paper(OFFSETS), b, 50, np.random.default_rng(1))
    assert not unsampled["flagged"] and np.isnan(unsampled["null_p95_of_aligned_mean_mm"])
    assert unsampled["status"] == "no null: no posterior samples of A"


def test_a_joint_one_campaign_did_not_see_is_in_the_null_at_the_marks_tolerance(iiwa):
    """A campaign that held joint 7's zero-offset at the controller's mark (its data did not see it)
    against one that estimated it 0.34 deg away: compared as if the mark were known, the difference is
    a flagged drift; with the held joint drawn at the marks' 0.5 deg (`Calibration.unseen_std`, as
    `remaster predict` draws it), the null holds it and nothing is flagged. Between two calibrations
    that both held it, joint 7 cancels and joint 2 moved by 0.01 deg is flagged; draws without an
    unseen joint take the generator as before."""
    rng = np.random.default_rng(7)
    q = random_configurations(iiwa, 300, rng)
    seen = paper(OFFSETS)
    seen = prediction.Calibration("paper", seen.values, draws=draws_around(seen, 1e-6, 400, rng))
    held_values = {**seen.values, "zero_offsets.q7": 0.0}
    held_draws = seen.draws.drop(columns=["zero_offsets.q7"])
    as_known = prediction.Calibration("paper", held_values, draws=held_draws)
    unseen = dataclasses.replace(as_known, unseen_std={"zero_offsets.q7": np.radians(0.5)})
    assert predictions.compare_predictions(iiwa, q, MARKER, seen, as_known, 100, np.random.default_rng(1))["flagged"]
    held = predictions.compare_predictions(iiwa, q, MARKER, seen, unseen, 100, np.random.default_rng(1))
    assert not held["flagged"] and held["null_p95_of_aligned_mean_mm"] > held["mean_mm"] > 0.5
    d = np.radians(0.01)
    moved = dataclasses.replace(
        unseen,
        values={**held_values, "zero_offsets.q2": OFFSETS[1] + d},
        draws=held_draws.assign(**{"zero_offsets.q2": held_draws["zero_offsets.q2"] + d}),
    )
    assert predictions.compare_predictions(iiwa, q, MARKER, unseen, moved, 100, np.random.default_rng(1))["flagged"]
    draws = [as_known.draw_values(5, np.random.default_rng(3)), unseen.draw_values(5, np.random.default_rng(3))]
    assert [d["zero_offsets.q2"] for d in draws[0]] == [d["zero_offsets.q2"] for d in draws[1]]
    assert {d["zero_offsets.q7"] for d in draws[0]} == {0.0} and len({d["zero_offsets.q7"] for d in draws[1]}) == 5


def one_tool_orientation(chain, count: int, rng) -> np.ndarray:
    """(count, 7) configurations whose flange points down, at positions drawn in front of the arm
    (the cubes of one tool orientation)."""
    solver = SRSInverseKinematics(chain)
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])
    out = []
    while len(out) < count:
        pose[:3, 3] = [rng.uniform(0.4, 0.7), rng.uniform(-0.3, 0.3), rng.uniform(0.2, 0.6)]
        solutions = solver.solve(pose)
        if len(solutions):
            out.append(solutions[0])
    return np.array(out)


def test_a_joint_held_on_one_tool_orientation_moves_the_predictions_rigidly_and_hides_no_drift(iiwa):
    """Cubes of one tool orientation cannot see joint 7's zero-offset: one calibration holds it at
    the mark (drawn at the marks' 0.5 deg), the other estimated it 0.64 deg away. At configurations
    of that orientation joint 7's turn moves every predicted marker by one vector, which
    re-registering the sensor absorbs: the change left after the best rigid motion is a few um and
    not flagged, though the robot-frame change is 1.1 mm. Joint 2 moved by 0.04 deg on top is
    flagged (what the rigid motion leaves of it, 0.03 mm, against a null of 0.002 mm); in the robot
    frame it adds 0.05 mm to the mean change, within the spread of the held joint's drawn turn."""
    rng = np.random.default_rng(5)
    q = one_tool_orientation(iiwa, 200, rng)
    seen = paper([*OFFSETS[:6], OFFSETS[6] + np.radians(0.3)])
    seen = prediction.Calibration("paper", seen.values, draws=draws_around(seen, 1e-6, 400, rng))
    held_values = {**seen.values, "zero_offsets.q7": 0.0}
    held = prediction.Calibration("paper", held_values, draws=seen.draws.drop(columns=["zero_offsets.q7"]))
    held = dataclasses.replace(held, unseen_std={"zero_offsets.q7": np.radians(0.5)})
    same = predictions.compare_predictions(iiwa, q, MARKER, seen, held, 100, np.random.default_rng(1))
    assert same["mean_mm"] > 1.0 and same["aligned_mean_mm"] < 0.01 and not same["flagged"]
    d = np.radians(0.04)
    moved = dataclasses.replace(
        held,
        values={**held_values, "zero_offsets.q2": OFFSETS[1] + d},
        draws=held.draws.assign(**{"zero_offsets.q2": held.draws["zero_offsets.q2"] + d}),
    )
    drift = predictions.compare_predictions(iiwa, q, MARKER, seen, moved, 100, np.random.default_rng(1))
    assert drift["flagged"] and drift["aligned_mean_mm"] > 10 * drift["null_p95_of_aligned_mean_mm"]


def test_prediction_drift_and_agreement_tables(iiwa, noisy):
    """Consecutive campaigns of one sensor kind, and the sensors of one campaign, with models of
    different effects still compared (by prediction)."""
    loop = prediction.Calibration("loop", loop_values(iiwa), ("link_geometry", "marker_offset"))
    models = {"nominal": prediction.Calibration("nominal"), "paper": paper(OFFSETS), "loop": loop}
    other = SensorData("motion_capture", "motion_capture", np.array([0.1, 0.0, 0.02]), 3e-5, noisy.table)
    entries = [
        entry(iiwa, "b", "2021-01-01", noisy, {**models, "paper": paper(OFFSETS + 1e-3)}),
        entry(iiwa, "a", "2020-01-01", noisy, models),
        entry(iiwa, "a", "2020-01-01", other, models),
    ]
    drift = predictions.prediction_drift(entries, n_configurations=50, seed=3, draw_pairs=10)
    assert list(drift.columns) == predictions.DRIFT_COLUMNS
    assert drift[["campaign_a", "campaign_b", "model"]].values.tolist() == [["a", "b", "paper"], ["a", "b", "loop"]]
    rows = drift.set_index("model")
    assert rows.loc["loop", "mean_mm"] == 0.0 and rows.loc["paper", "mean_mm"] > 0.1
    # the marker is the campaigns' set-up, not the robot: left out of the drift as of the agreement
    assert rows.loc["loop", "effects_a"] == "link_geometry"
    again = predictions.prediction_drift(entries, n_configurations=50, seed=3, draw_pairs=10)
    pd.testing.assert_frame_equal(drift, again)  # one fixed set of configurations per robot and seed
    agreement = predictions.prediction_agreement(entries, n_configurations=50, seed=3, draw_pairs=10)
    assert list(agreement.columns) == predictions.AGREEMENT_COLUMNS
    assert agreement[["sensor_a", "sensor_b"]].drop_duplicates().values.tolist() == [
        ["motion_capture", "laser_tracker"]
    ]
    # the marker offset is each sensor's own: left out between sensors
    assert set(agreement["effects_a"]) == {"none", "link_geometry"} and (agreement["mean_mm"] == 0.0).all()


def test_a_remounted_marker_is_no_drift_with_or_without_a_marker_offset(iiwa, noisy):
    """A reflector remounted between two campaigns of one robot. Where the loop models fitted a
    marker offset, the second held joint 7 at the mark (its offset carried the turn); where a model
    has no marker offset, its joint 7 estimate carries the mount (the marker's tangential move reads
    as a turn). Either way the comparison leaves the set-up out, joint 7 drawn in both at what the
    mount leaves open (1 mm over the marker's 0.1 m from the axis), and one marker's position cannot
    tell the turn from the mount: the predictions are compared at the marker's foot on joint 7's
    axis, which the turn does not move: no drift. A full-pose probe's orientations tell the turn
    from the mount: there the marker itself is compared, and the same turn flagged."""
    rng = np.random.default_rng(5)
    values = {f"zero_offsets.q{j + 1}": float(v) for j, v in enumerate(OFFSETS)}
    values.update({"marker_offset.x": 4e-4, "marker_offset.y": 0.0, "marker_offset.z": -3e-4})

    def with_draws(c: prediction.Calibration) -> prediction.Calibration:
        draws = {n: v + 1e-6 * rng.standard_normal(300) for n, v in c.values.items()}
        return dataclasses.replace(c, draws=pd.DataFrame(draws))

    def drift(first, second, sensor=noisy):
        entries = [
            entry(iiwa, "a", "2020-01-01", sensor, {first.model: first}),
            entry(iiwa, "b", "2021-01-01", sensor, {second.model: second}),
        ]
        return predictions.prediction_drift(entries, n_configurations=50, seed=3, draw_pairs=50).iloc[0]

    first = with_draws(prediction.Calibration("loop", values, ("marker_offset",)))
    remounted = {**values, "marker_offset.x": -6e-4, "marker_offset.z": 5e-4, "zero_offsets.q7": 0.0}
    held = first.draws.drop(columns=["zero_offsets.q7"]).assign(**{"marker_offset.x": -6e-4, "marker_offset.z": 5e-4})
    second = prediction.Calibration("loop", remounted, ("marker_offset",), draws=held)
    second = dataclasses.replace(
        second, unseen_std={"zero_offsets.q7": np.radians(0.5)}, carried=frozenset({"zero_offsets.q7"})
    )
    mount = 1e-3 / 0.1  # rad: the default marker prior over the marker's distance from joint 7's axis
    robot = predictions._without_set_up(entry(iiwa, "b", "2021-01-01", noisy, {"loop": second})).models["loop"]
    assert robot.blocks == () and robot.drawn_unseen == {"zero_offsets.q7": pytest.approx(mount)}
    row = drift(first, second)
    assert row["status"] == "compared" and not row["flagged"]
    assert row["mean_mm"] < 1e-3  # joint 7's turn moves nothing on its axis
    # no marker offset: the mount read as joint 7 turned by 0.3 deg
    turned = {**values, "zero_offsets.q7": values["zero_offsets.q7"] + np.radians(0.3)}
    paper_a, paper_b = (with_draws(paper([v[f"zero_offsets.q{j + 1}"] for j in range(7)])) for v in (values, turned))
    row = drift(paper_a, paper_b)
    assert row["mean_mm"] < 1e-3 and not row["flagged"]
    # what the mount's turn no longer hides: joint 2 moved by 0.01 deg, flagged
    shifted = {**values, "zero_offsets.q2": values["zero_offsets.q2"] + np.radians(0.01)}
    paper_c = with_draws(paper([shifted[f"zero_offsets.q{j + 1}"] for j in range(7)]))
    row = drift(paper_a, paper_c)
    assert row["flagged"] and row["aligned_mean_mm"] > 10 * row["null_p95_of_aligned_mean_mm"]
    assert row["beyond_null"] and row["loops_closed"] is None  # verdicts not given: flagged as before
    # beyond the null between a loop that closed and one that did not: shown, not the robot's drift
    verdicts = [
        entry(iiwa, "a", "2020-01-01", noisy, {"paper": paper_a})._replace(loop_closed=True),
        entry(iiwa, "b", "2021-01-01", noisy, {"paper": paper_c})._replace(loop_closed=False),
    ]
    row = predictions.prediction_drift(verdicts, n_configurations=50, seed=3, draw_pairs=50).iloc[0]
    assert row["beyond_null"] and row["loops_closed"] is not None and not row["loops_closed"] and not row["flagged"]
    # a full-pose probe sees the turn apart from the mount: compared, and the 0.3 deg turn flagged
    probe = dataclasses.replace(noisy, table=noisy.table.assign(rx=0.0, ry=0.0, rz=0.0))
    assert probe.has_orientation
    row = drift(paper_a, paper_b, probe)
    assert row["mean_mm"] > 0.3 > row["null_p95_of_aligned_mean_mm"] and row["flagged"]


def test_transfer_heat_map(iiwa, noisy):
    models = {"paper": paper(OFFSETS)}
    other = SensorData("motion_capture", "motion_capture", MARKER, 3e-5, noisy.table)
    entries = [
        entry(iiwa, c, d, s, models) for c, d in (("a", "2020-01-01"), ("b", "2021-01-01")) for s in (noisy, other)
    ]
    table = transfer.transfer_table(entries)
    assert len(table) == 8  # 2 sensors x 2 x 2 campaigns
    fig = figures_comparison.transfer_figure(table, "Transfer, paper model")
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["Motion Capture", "Laser Tracker"]
    assert len(panels[0].texts) == 4
    plt.close(fig)
    with pytest.raises(ValueError, match="one model"):
        figures_comparison.transfer_figure(pd.concat([table, table.assign(model="loop")]), "mixed")


def test_drift_is_compared_where_both_campaigns_measured_one_turn_apart_included(iiwa, noisy):
    """Inside both campaigns' domains: the same configurations with joint 1 read one turn away
    (q1 - 2 pi, as a UR reaches a pose again) are the same domain; a campaign measured with joint 1
    elsewhere shares none, and its drift is not compared (its calibration there is its priors')."""
    models = {"paper": paper(OFFSETS)}

    def moved(shift: float, scale: float = 1.0) -> SensorData:
        table = noisy.table.copy()
        table["q1"] = scale * table["q1"] + shift
        return dataclasses.replace(noisy, table=table)

    turned = [entry(iiwa, "a", "2020-01-01", noisy, models), entry(iiwa, "b", "2021-01-01", moved(-2 * np.pi), models)]
    shared = predictions.shared_configurations(*turned, 200, seed=3)
    # every draw near a's data is near b's (b's own, one turn out, are clipped to the iiwa's limits)
    assert len(shared) > 0.8 * 200
    drift = predictions.prediction_drift(turned, n_configurations=200, seed=3, draw_pairs=10)
    assert drift["count"].iloc[0] == len(shared) and drift["mean_mm"].iloc[0] == 0.0 and not drift["flagged"].iloc[0]
    narrow, opposite = moved(0.0, 0.3), moved(np.pi, 0.3)  # joint 1 within +-0.5 rad, and half a turn away
    apart = [entry(iiwa, "a", "2020-01-01", narrow, models), entry(iiwa, "b", "2021-01-01", opposite, models)]
    drift = predictions.prediction_drift(apart, n_configurations=200, seed=3, draw_pairs=10)
    row = drift.iloc[0]
    assert row["status"].startswith("not compared") and not row["flagged"] and np.isnan(row["mean_mm"])
    assert row["count"] < predictions.MIN_SHARED_CONFIGURATIONS


def test_a_change_between_campaigns_a_turn_apart_is_shown_not_flagged(iiwa, noisy):
    """Campaign b measured a's configurations with joint 1 read one turn away. A model periodic in
    joint 1 sees the same configurations, but the robot is the same there only if all it does is
    periodic in the turn: a change of prediction beyond the null is shown (`beyond_null`,
    `turn_apart`), not flagged as drift. Where b measured a's own readings, the same change is flagged."""
    rng = np.random.default_rng(7)
    shifted = OFFSETS + np.radians([0.0, 0.01, 0, 0, 0, 0, 0])
    draws = [
        pd.DataFrame({f"zero_offsets.q{j + 1}": v + 1e-6 * rng.standard_normal(50) for j, v in enumerate(o)})
        for o in (OFFSETS, shifted)
    ]
    first, second = paper(OFFSETS, draws[0]), paper(shifted, draws[1])
    table = noisy.table.copy()
    table["q1"] -= 2 * np.pi
    for sensor, apart in ((dataclasses.replace(noisy, table=table), True), (noisy, False)):
        entries = [
            entry(iiwa, "a", "2020-01-01", noisy, {"paper": first}),
            entry(iiwa, "b", "2021-01-01", sensor, {"paper": second}),
        ]
        row = predictions.prediction_drift(entries, n_configurations=200, seed=3, draw_pairs=50).iloc[0]
        assert row["beyond_null"] and row["aligned_mean_mm"] > 10 * row["null_p95_of_aligned_mean_mm"]
        assert row["count"] >= predictions.MIN_SHARED_CONFIGURATIONS
        assert bool(row["turn_apart"]) is apart and bool(row["flagged"]) is not apart
        assert (row["status"] == predictions.TURN_APART) is apart


def test_a_joint_scale_is_not_periodic_its_model_is_not_compared_one_turn_apart(iiwa, noisy):
    """Campaign b read joint 1 one turn from a's readings. The zero-offset model is periodic in it:
    its drift is compared there, as before. A loop model with a joint scale on joint 1 corrects in
    proportion to the reading, so what b measured at q1 - 2 pi says nothing of it at q1: nearness
    takes joint 1 on the line for that model, few configurations are shared, its drift is not compared."""
    scaled = prediction.Calibration("loop", {**paper(OFFSETS).values, "joint_scale.q1": 3e-4}, ("joint_scale",))
    models = {"paper": paper(OFFSETS), "loop": scaled}
    table = noisy.table.copy()
    table["q1"] -= 2 * np.pi
    turned = [
        entry(iiwa, "a", "2020-01-01", noisy, models),
        entry(iiwa, "b", "2021-01-01", dataclasses.replace(noisy, table=table), models),
    ]
    on_circle = predictions.shared_configurations(*turned, 200, seed=3, model="paper")
    on_line = predictions.shared_configurations(*turned, 200, seed=3, model="loop")
    assert len(on_circle) > 0.8 * 200 and len(on_line) < predictions.MIN_SHARED_CONFIGURATIONS
    np.testing.assert_array_equal(on_circle, predictions.shared_configurations(*turned, 200, seed=3))
    drift = predictions.prediction_drift(turned, n_configurations=200, seed=3, draw_pairs=10).set_index("model")
    assert drift.at["paper", "status"] == "no null: no posterior samples of A and B"
    assert drift.at["paper", "count"] == len(on_circle) and drift.at["paper", "mean_mm"] == 0.0
    assert drift.at["loop", "status"].startswith("not compared") and drift.at["loop", "count"] == len(on_line)
    assert not drift["flagged"].any()
