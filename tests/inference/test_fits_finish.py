"""Fits that finish on any serial arm: every undetermined combination is held, by the
Laplace fit's own test, and stated; the default sampler runs until its criteria hold; samplers
that disagree are marked, not fatal; no diagnostic crashes on a NaN or a missing value."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from remaster import api, diagnostics, files
from remaster.campaigns.campaign import sensor_data
from remaster.campaigns.simulation import Sensor, TrueRobot, looking_at, measure
from remaster.inference import fit, identifiability
from remaster.inference.blocks import paper_model
from remaster.inference.cross_check import cross_check, disagreeing
from remaster.inference.laplace_report import LaplaceReport, laplace_fit, laplace_report
from remaster.inference.least_squares import NotIdentifiable, least_squares_laplace
from remaster.inference.model import display_scale
from remaster.inference.posterior_sampling import (
    converged,
    overdispersed_starts,
    sample,
    sampler_diagnostics,
    samples_frame,
)
from remaster.inference.posterior_summary import posterior_summary
from remaster.inference.sampling.chains import extend
from remaster.inference.sampling.metropolis import metropolis_adaptive
from remaster.inference.sampling.target import CallableTarget, Chain
from remaster.robot import ik, kinematics

CRITERIA = {"max_rhat": 1.05, "min_ess": 200}


def sensor_table(chain, q, marker, truth, rng, noise=5e-5, seen=None, kind="laser_tracker"):
    """A sensor's table of configurations q (n, N) measured with known zero-offsets `truth`;
    rows outside `seen` (default all) not seen by the sensor."""
    n = len(q)
    sensor = Sensor(kind, kind, looking_at([1.8, 0.2, 1.3], [0, 0, 0.6]), noise, np.asarray(marker, dtype=float))
    xyz = measure(chain, TrueRobot(zero_offsets=truth), sensor, q, rng)
    if seen is not None:
        xyz[np.setdiff1d(np.arange(n), seen)] = np.nan
    table = pd.DataFrame(
        {"set": "optimization", "pose": np.arange(n, dtype=np.int64), "solution": np.zeros(n, np.int64)}
    )
    for j in range(chain.n_joints):
        table[f"q{j + 1}"] = q[:, j]
    table[["x", "y", "z"]] = xyz
    spec = {"kind": kind, "marker": list(marker), "noise": noise}
    return sensor_data(kind, spec, table, chain.n_joints, "simulated.parquet")


def laplace_of(chain, sensor):
    """(model, identifiability, LaplaceReport as later stages read it) of one sensor."""
    registration = fit.register(chain, sensor)
    model, analysis, excluded = fit.build_model(chain, sensor, registration.t_nr)
    content = laplace_report(laplace_fit(model), analysis, excluded, (), model)
    return model, analysis, LaplaceReport.of(json.loads(json.dumps(content)))


# ----------------------------------------------------------------------------- identifiability


@pytest.mark.parametrize("off_axis", [0.0, 1e-6])
def test_a_7_axis_arm_with_joints_1_and_7_still_and_the_marker_on_axis_7(iiwa, off_axis):
    """q1 = q7 = 0 in every row and the marker on joint 7's axis (exactly, or 1 um off as a
    frame's round-off leaves it). Then joint 7's offset moves no point, and with joint 1 still,
    joint 2's axis is fixed in the base frame: its offset is a rigid rotation of every point, as
    joint 1's is, and the registration absorbs both. So exactly q1, q2 and q7 are held, each
    stated with its combination, and the fit and the default sampler finish.

    At 1 um the old analysis (SI Jacobian, 1e-7) let q7 through while the Laplace fit (step
    units, 1e-6) refused it: the column's SI ratio is above 1e-7, its step-unit ratio below 1e-6."""
    rng = np.random.default_rng(7)
    q = rng.uniform(np.maximum(iiwa.lower, -2.0), np.minimum(iiwa.upper, 2.0), (60, 7))
    q[:, 0] = q[:, 6] = 0.0
    marker = [off_axis, 0.0, 0.05]
    truth = rng.normal(0.0, np.radians(0.3), 7)
    sensor = sensor_table(iiwa, q, marker, truth, rng)
    full = paper_model(iiwa, q, sensor.table[["x", "y", "z"]].to_numpy(), marker, fit.register(iiwa, sensor).t_nr)
    if off_axis:  # the premise: a combination between the two old tests
        jacobian = full.jacobian(np.zeros(13), identifiability.JACOBIAN_STEP)
        si = np.linalg.norm(jacobian, axis=0)
        steps = np.linalg.norm(jacobian * full.scale, axis=0)
        assert si[-1] / np.linalg.svd(jacobian, compute_uv=False)[0] > 1e-7
        assert steps[-1] / np.linalg.svd(jacobian * full.scale, compute_uv=False)[0] < 1e-6

    model, analysis, laplace = laplace_of(iiwa, sensor)
    assert set(laplace.held) == {"zero_offsets.q1", "zero_offsets.q2", "zero_offsets.q7"}
    assert len(laplace.null_directions) == 3
    # each held parameter with the combination it stood for: q7 alone (it moves nothing), q1 and
    # q2 against the registration
    combinations = analysis.report()["held_combinations"]
    assert combinations["zero_offsets.q7"] == {"zero_offsets.q7": 1.0}
    for joint in ("zero_offsets.q1", "zero_offsets.q2"):
        assert combinations[joint][joint] == 1.0
        assert any(n.startswith("registration.") for n in combinations[joint])
    assert len(laplace.held_statements) == 3
    assert any(
        s.startswith("zero_offsets.q7 is held") and "changes no measured point" in s for s in laplace.held_statements
    )
    # the free parameters pass the fit's own test: no NotIdentifiable, and the offsets the data
    # see come back within 4 std
    assert laplace.names == model.names and "zero_offsets.q7" not in laplace.names
    for j in (3, 4, 5, 6):
        k = laplace.names.index(f"zero_offsets.q{j}")
        assert abs(laplace.theta_map[k] - truth[j - 1]) < 4 * laplace.std[k]
    # the default sampler runs on the reduced model and the summary states the held joints
    settings = {"chains": 2, "samples": 3000, "burn_in": 1000, "convergence": CRITERIA, "max_doublings": 2}
    chains = sample(model, laplace, "default", settings, np.random.default_rng(1))
    summary = posterior_summary(samples_frame(chains), laplace)
    assert (summary.loc[["zero_offsets.q1", "zero_offsets.q2", "zero_offsets.q7"], "status"] != "estimated").all()
    assert (summary.drop(["zero_offsets.q1", "zero_offsets.q2", "zero_offsets.q7"])["status"] == "estimated").all()


def test_the_marker_on_axis_statement_names_what_the_data_cannot_see(iiwa):
    """The statement of a parameter that moves no point at all says so, with no other parameter."""
    rng = np.random.default_rng(8)
    q = rng.uniform(np.maximum(iiwa.lower, -2.0), np.minimum(iiwa.upper, 2.0), (40, 7))
    sensor = sensor_table(iiwa, q, [0.0, 0.0, 0.05], np.zeros(7), rng)
    _, analysis, laplace = laplace_of(iiwa, sensor)
    assert set(laplace.held) == {"zero_offsets.q1", "zero_offsets.q7"}
    assert analysis.combinations["zero_offsets.q7"] == {"zero_offsets.q7": 1.0}
    statement = next(s for s in laplace.held_statements if s.startswith("zero_offsets.q7"))
    assert "1 deg of it changes no measured point" in statement


def near_collinear_configurations(chain, marker, rng, n=6, off_line=2e-3):
    """n configurations (IK) whose marker positions lie on a 0.6 m line but for +-off_line (m)
    across it, with varied orientations and elbows."""
    from scipy.spatial.transform import Rotation

    direction = np.array([0.0, 0.6, 0.1])
    across = np.cross(direction, [1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    solver = ik.SRSInverseKinematics(chain)
    configurations = []
    for k, t in enumerate(np.linspace(0.0, 1.0, n)):
        point = np.array([0.55, -0.3, 0.45]) + t * direction + off_line * (-1) ** k * across
        for _ in range(200):
            angles = [math.pi + rng.normal(0, 0.4), rng.normal(0, 0.4), rng.uniform(-2, 2)]
            rotation = Rotation.from_euler("xyz", angles).as_matrix()
            pose = np.eye(4)
            pose[:3, :3], pose[:3, 3] = rotation, point - rotation @ marker
            solutions = solver.solve(pose, q3=rng.uniform(-0.5, 0.5))
            if len(solutions):
                configurations.append(solutions[0])
                break
    assert len(configurations) == n
    return np.array(configurations)


def test_a_sensor_that_sees_a_handful_of_near_collinear_points(iiwa):
    """A motion-capture sensor sees 6 of 40 configurations, their markers within 2 mm of one
    line: the rotation about that line is weakly determined (not undetermined), so only joint 1
    is held, it is stated, and the Laplace fit, the default sampler (run on to its bound of
    doublings by the slow weak direction) and the cross-check finish."""
    rng = np.random.default_rng(4)
    marker = np.array([0.05, 0.0, 0.03])
    q = rng.uniform(np.maximum(iiwa.lower, -2.0), np.minimum(iiwa.upper, 2.0), (40, 7))
    seen = np.sort(rng.choice(40, 6, replace=False))
    q[seen] = near_collinear_configurations(iiwa, marker, rng)
    truth = rng.normal(0.0, np.radians(0.3), 7)
    sensor = sensor_table(iiwa, q, marker, truth, rng, noise=2e-5, seen=seen, kind="motion_capture")
    points = kinematics.marker_positions(iiwa, q[seen], marker)
    centred = points - points.mean(axis=0)
    along = np.linalg.svd(centred)[2][0]
    off_line = np.linalg.norm(centred - np.outer(centred @ along, along), axis=1)
    assert off_line.max() < 3e-3 and np.ptp(centred @ along) > 0.5  # within 3 mm of a 0.6 m line
    model, analysis, laplace = laplace_of(iiwa, sensor)
    assert laplace.held == {"zero_offsets.q1": 0.0} and model.n_points == 6
    assert laplace.marker_not_seen_rows == tuple(np.setdiff1d(np.arange(40), seen))
    assert laplace.held_statements[0].startswith("zero_offsets.q1 is held")
    assert "registration." in laplace.held_statements[0]
    settings = {"chains": 2, "samples": 4000, "burn_in": 1500, "convergence": CRITERIA, "max_doublings": 2}
    chains = sample(model, laplace, "default", settings, np.random.default_rng(2))
    report = sampler_diagnostics(chains, 1.0)
    samples = {"default": samples_frame(chains)}
    table = cross_check(samples, {"default": report}, laplace, tolerance=4.0, floor=0.1, **CRITERIA)
    assert set(table["parameter"]) == set(laplace.names) | {"noise.sigma"}
    # the weak direction makes the chains slow: they ran on to the bound, and agree with Laplace
    assert report["doublings"] == 2 and report["kept_per_chain"] == 2500 * 4
    assert disagreeing(table) == {} and table["checked_laplace"].all()


def test_a_registration_only_direction_holds_the_registration_parameter_with_the_largest_share():
    """Synthetic Jacobians with a known null space. A direction in the registration alone holds
    the registration parameter with the largest share (step units: a mm of x is worth 2 of y);
    a direction a zero-offset takes part in holds the zero-offset even when a registration
    parameter has a larger share; the rest then pass `least_squares_laplace`'s own test."""
    rng = np.random.default_rng(3)
    names = ["registration.x", "registration.y", "registration.alpha", "zero_offsets.q2", "zero_offsets.q3"]
    scale = np.array([display_scale(n) for n in names])
    steps = rng.normal(size=(30, 5))  # columns in step units
    steps[:, 1] = 0.5 * steps[:, 0]  # y undoes twice itself in x: null direction (1, -2) in (x, y)
    steps[:, 4] = 100.0 * steps[:, 2]  # q3 = 100 x alpha: null direction (100, -1) in (alpha, q3)
    jacobian = steps / scale
    combinations, directions = identifiability.hold_undetermined(jacobian, names, scale)
    assert set(combinations) == {"registration.y", "zero_offsets.q3"} and len(directions) == 2
    assert combinations["registration.y"] == pytest.approx({"registration.y": 1.0, "registration.x": -0.5})
    assert combinations["zero_offsets.q3"] == pytest.approx({"zero_offsets.q3": 1.0, "registration.alpha": -100.0})
    free = [i for i, n in enumerate(names) if n not in combinations]
    y = rng.normal(size=30)
    result = least_squares_laplace(
        lambda b: y - jacobian[:, free] @ b, np.zeros(len(free)), scale[free], names=[names[i] for i in free]
    )
    assert np.all(np.isfinite(result.std))
    # a registration direction with the larger share on x holds x
    steps[:, 1] = 2.0 * steps[:, 0]
    steps[:, 4] = rng.normal(size=30)
    combinations, _ = identifiability.hold_undetermined(steps / scale, names, scale)
    assert combinations == {"registration.x": pytest.approx({"registration.x": 1.0, "registration.y": -0.5})}


def test_the_analysis_and_the_fit_apply_one_test():
    """A combination that the old tests left between them: in SI (metres, radians) its singular
    value is above the old analysis's 1e-7, in step units (mm, deg) below the fit's 1e-6, so the
    old analysis let it through and the fit refused it (NotIdentifiable). The analysis now holds
    it (y: the registration parameter with the larger share, no zero-offset taking part), and the
    fit accepts what is left."""
    names = ["registration.x", "registration.y", "zero_offsets.q2"]
    scale = np.array([display_scale(n) for n in names])
    rng = np.random.default_rng(5)
    steps = rng.normal(size=(20, 3))
    steps[:, 1] = steps[:, 0] / 1.02 + 5e-5 * rng.normal(size=20)  # 1.02 mm of y nearly undo 1 mm of x
    steps[:, 2] *= 100.0  # the joint's column dominates in step units, the translations' in SI
    jacobian = steps / scale
    si = np.linalg.svd(jacobian, compute_uv=False)
    singular, _, _ = identifiability.undetermined_directions(jacobian, scale)
    assert si[-1] > 1e-7 * si[0] and singular[-1] < identifiability.RCOND * singular[0]
    y = rng.normal(size=20)
    with pytest.raises(NotIdentifiable, match="registration.x"):
        least_squares_laplace(lambda b: y - jacobian @ b, np.zeros(3), scale, names=names)
    combinations, directions = identifiability.hold_undetermined(jacobian, names, scale)
    assert list(combinations) == ["registration.y"] and len(directions) == 1
    assert combinations["registration.y"] == pytest.approx(
        {"registration.y": 1.0, "registration.x": -1 / 1.02}, rel=1e-3
    )
    free = [0, 2]
    result = least_squares_laplace(lambda b: y - jacobian[:, free] @ b, np.zeros(2), scale[free])
    assert np.all(np.isfinite(result.std))
    assert identifiability.RELATIVE_THRESHOLD == 2 * identifiability.RCOND


# ----------------------------------------------------------------------------- the default sampler


def test_the_default_sampler_doubles_until_its_criteria_hold(iiwa):
    """A first run too short for the criteria (ESS >= 200) runs on: its kept steps double, the
    first part unchanged, until they hold; without criteria (or max_doublings 0) it does not."""
    from .test_fit import simulated_sensor

    rng = np.random.default_rng(12)
    sensor, _ = simulated_sensor(iiwa, rng, n=40)
    model, _, laplace = laplace_of(iiwa, sensor)
    short = {"chains": 2, "samples": 1600, "burn_in": 1000}
    once = sample(model, laplace, "default", short, np.random.default_rng(3))
    first = sampler_diagnostics(once, 1.0)
    assert not converged(first, **CRITERIA) and first["kept_per_chain"] == 600 and first["doublings"] == 0
    doubled = sample(
        model, laplace, "default", {**short, "convergence": CRITERIA, "max_doublings": 5}, np.random.default_rng(3)
    )
    report = sampler_diagnostics(doubled, 1.0)
    assert report["doublings"] >= 1 and report["kept_per_chain"] == 600 * 2 ** report["doublings"]
    assert converged(report, **CRITERIA)
    for before, after in zip(once, doubled):  # the same chains, only longer
        assert np.array_equal(after.samples[: before.n_steps], before.samples)
    capped = sample(
        model, laplace, "default", {**short, "convergence": CRITERIA, "max_doublings": 0}, np.random.default_rng(3)
    )
    assert np.array_equal(capped[0].samples, once[0].samples)


def test_the_default_sampler_starts_from_the_laplace_approximation():
    """Starts are MAP + 3 L z with L L^T the Laplace covariance: their spread follows its shape
    (a correlation of 0.99 stays 0.99), and sigma stays positive."""
    covariance = np.array([[1.0, 0.99, 0.0], [0.99, 1.0, 0.0], [0.0, 0.0, 0.25]]) * 1e-8
    start = np.array([1e-3, -1e-3, 5e-5])
    starts = overdispersed_starts(start, covariance, 20_000, np.random.default_rng(0))
    spread = np.cov((starts - start).T)
    assert np.corrcoef((starts - start)[:, :2].T)[0, 1] == pytest.approx(0.99, abs=0.002)
    assert np.sqrt(spread[0, 0]) == pytest.approx(3e-4, rel=0.02)
    assert np.all(starts[:, -1] > 0)


def test_an_extended_chain_samples_the_same_posterior():
    """`extend` continues a chain with its frozen proposal: on a Gaussian with known
    moments the doubled chain's mean and std are right, and its acceptance counts both parts."""
    names = ("a", "noise.sigma")
    mean, std = np.array([1e-3, 2e-4]), np.array([1e-4, 1e-5])

    def many(thetas):
        return -0.5 * np.sum(((thetas - mean) / std) ** 2, axis=1)

    target = CallableTarget(names, np.array([1e-3, 1e-3]), many)
    chain = metropolis_adaptive(target, np.random.default_rng(1), mean, n_samples=6000, burn_in=2000)
    longer = extend(target, np.random.default_rng(2), chain, chain.n_steps)
    assert longer.n_steps == 2 * chain.n_steps and longer.settings["doublings"] == 1
    assert np.array_equal(longer.samples[: chain.n_steps], chain.samples)
    report = diagnostics.chain_report([longer])
    np.testing.assert_allclose(report["mean"], mean, atol=4 * report["mcse"].max() + 1e-9)
    np.testing.assert_allclose(report["std"], std, rtol=0.1)
    assert 0.1 < longer.acceptance_rate < 0.6
    ensemble = Chain(np.zeros((4, 2)), np.zeros(4), 0.5, names, "emcee", {}, n_walkers=2)
    with pytest.raises(ValueError, match="emcee chain cannot be extended"):
        extend(target, np.random.default_rng(0), ensemble, 10)


# ----------------------------------------------------------------------------- NaN and missing values


@pytest.mark.parametrize(
    "report",
    [
        {"max_rhat": None, "min_ess": 500.0},
        {"max_rhat": math.nan, "min_ess": 500.0},
        {"max_rhat": 1.0, "min_ess": None},
        {"min_ess": 500.0},
        {},
        None,
        {"max_rhat": "n/a", "min_ess": 500.0},
    ],
)
def test_converged_is_false_not_a_crash_on_a_missing_value(report):
    assert converged(report, 1.05, 200) is False


def test_converged_on_numbers():
    assert converged({"max_rhat": 1.01, "min_ess": 300}, 1.05, 200) is True
    assert converged({"max_rhat": 1.2, "min_ess": 300}, 1.05, 200) is False


def test_a_chain_that_never_moves_has_no_rhat_and_is_not_converged(tmp_path):
    """A parameter constant in every chain: R-hat NaN (no spread to compare), reported as such
    (not skipped by the max), written as null, and read back as not converged."""
    rng = np.random.default_rng(0)
    names = ("a", "stuck", "noise.sigma")
    chains = []
    for _ in range(2):
        samples = rng.normal(size=(4000, 3))
        samples[:, 1] = 0.25
        chains.append(Chain(samples, np.zeros(4000), 0.3, names, "metropolis_adaptive", {}))
    report = sampler_diagnostics(chains, 2.0)
    assert math.isnan(report["max_rhat"]) and report["rhat_undefined"] == ["stuck"]
    assert report["min_ess"] == pytest.approx(2.0)  # the stuck parameter: one effective sample per chain
    assert not converged(report, 1.05, 1.0)
    path = files.write_json(tmp_path / "diagnostics.json", report)
    read = files.read_json(path)
    assert read["max_rhat"] is None and not converged(read, 1.05, 1.0)


def test_chain_report_and_moments_on_nan_and_empty_chains():
    rng = np.random.default_rng(1)
    good = rng.normal(size=(500, 2))
    holed = good.copy()
    holed[7, 1] = np.nan
    report = diagnostics.chain_report([holed, good], ["x", "y"])
    assert np.isfinite(report.loc["x"].drop("tau_reliable").astype(float)).all()
    assert math.isnan(report.loc["y", "mean"]) and math.isnan(report.loc["y", "rhat"])
    mean, std, mcse = diagnostics.moments([holed, good])
    assert math.isnan(mean[1]) and np.isfinite(mean[0])
    empty = diagnostics.chain_report([np.zeros((0, 2)), np.zeros((0, 2))], ["x", "y"])
    assert (
        empty["mean"].isna().all() and (empty[["ess_bulk", "ess_tail"]] == 0).all().all() and empty["rhat"].isna().all()
    )
    short = diagnostics.chain_report([np.ones((3, 2)), np.ones((3, 2))], ["x", "y"])
    assert short["rhat"].isna().all() and (short["mean"] == 1).all()
    # a NaN mean is a disagreement in the cross-check, marked, not raised, by `disagreements`
    table = diagnostics.cross_check(
        {"ref": diagnostics.moments([good]), "holed": (mean, std, mcse)}, ["x", "y"], tolerance=None, floor=0.1
    )
    assert diagnostics.disagreements(table, 4.0) == [("y", "holed", "ref", pytest.approx(math.nan, nan_ok=True))]


# ----------------------------------------------------------------------------- the arms real calibrations meet

HELD = {  # what each kind of `arm_kinds` leaves undetermined, by its construction
    "joints_one_and_seven_held": {"zero_offsets.q1", "zero_offsets.q2"},  # q1 still: q2 a rigid rotation too
    "ur5_with_dh_errors": {"zero_offsets.q1", "zero_offsets.q6"},  # the marker on the UR5's last axis
}


@pytest.mark.parametrize("kind", ["joints_one_and_seven_held", "marker_near_last_axis", "ur5_with_dh_errors"])
def test_the_prepare_stage_finishes_on_the_arms_real_calibrations_meet(kind, tmp_path):
    """The registration, outlier screen, identifiability analysis and Laplace fit of each sensor
    finish, hold what the kind leaves undetermined (joint 1 alone where nothing else is), and
    state each held parameter in laplace.json."""
    from remaster.campaigns import folders

    from ..campaigns.test_arm_kinds import simulated
    from ..conftest import REPO

    spec, _, out = simulated(kind)
    campaign = folders.read_campaign(folders.write_campaign(tmp_path / spec["name"], out.metadata, out.tables), REPO)
    for sensor in campaign.sensors:
        _, content = fit.prepare_stage(campaign, sensor, api.settings()["outliers"])
        laplace = LaplaceReport.of(json.loads(json.dumps(files.plain(content))))
        assert set(laplace.held) == HELD.get(kind, {"zero_offsets.q1"})
        assert [s.split(" ")[0] for s in laplace.held_statements] == list(laplace.held)
        assert np.all(np.isfinite(laplace.std))


def test_the_fit_summary_goes_on_when_the_samplers_disagree():
    """The bundled twin's laser tracker with emcee's samples shifted by 5 posterior std on joint
    3: the fit summary stage (cross-check, summary, discrepancy, remastering, accuracy) finishes,
    its cross-check marks joint 3 and emcee, and the summary is the default sampler's."""
    from remaster.campaigns import folders
    from remaster.evaluation import fit_summary

    from ..conftest import REPO

    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-twin", repo_root=REPO)
    registration, content = fit.prepare_stage(campaign, "laser_tracker", api.settings()["outliers"])
    registration = fit.Registration.of(registration)
    laplace = LaplaceReport.of(json.loads(json.dumps(files.plain(content))))
    model, _, _ = fit.build_model(
        campaign.chain, campaign.sensors["laser_tracker"], registration.t_nr, exclude=laplace.outlier_rows
    )
    samples, reports = {}, {}
    for method, settings in (
        ("default", {"chains": 2, "samples": 12000, "burn_in": 2000}),
        ("emcee", {"walkers": 32, "steps": 1500, "burn_in": 500}),
    ):
        chains = sample(model, laplace, method, settings, np.random.default_rng(3))
        samples[method], reports[method] = samples_frame(chains), sampler_diagnostics(chains, 1.0)
    samples["emcee"]["zero_offsets.q3"] += 5 * samples["emcee"]["zero_offsets.q3"].std()
    result = fit_summary.fit_summary_stage(
        campaign,
        "laser_tracker",
        registration,
        laplace,
        samples,
        reports,
        np.random.default_rng(4),
        fit_summary.SummarySettings({"tolerance": 4.0, "max_rhat": 1.5, "min_ess": 50, "floor": 0.1}, 50, 20),
    )
    assert disagreeing(result.cross_check) == {"zero_offsets.q3": ["emcee"]}
    summary = result.summary.set_index("parameter")
    assert summary.loc["zero_offsets.q3", "mean"] == pytest.approx(samples["default"]["zero_offsets.q3"].mean())
    assert len(result.remastering["joints"]) == 7 and "report" in result.accuracy
