"""The zero-offset fit end to end: coverage of the truth over many simulated campaigns, the
samplers' agreement, recovery on the bundled twin, and the remastering outputs."""

import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from remaster import files
from remaster.api.truth import link_turns
from remaster.campaigns import folders, scenario
from remaster.campaigns.campaign import sensor_data
from remaster.campaigns.simulation import Sensor, TrueRobot, looking_at, measure
from remaster.diagnostics import moments
from remaster.errors import InputError
from remaster.inference import cross_check as cross_check_module
from remaster.inference import fit, posterior_targets
from remaster.inference.cross_check import cross_check, disagreeing
from remaster.inference.laplace_report import LaplaceReport, laplace_fit, laplace_report
from remaster.inference.posterior_sampling import sample, sampler_diagnostics, samples_frame
from remaster.inference.posterior_summary import posterior_summary, remastering
from remaster.inference.posterior_targets import PosteriorTarget

from ..conftest import REPO

FAST = {
    "paper": {"chains": 2, "samples": 4000, "burn_in": 3000, "half_width": 0.0125},
    "default": {"chains": 2, "samples": 5000, "burn_in": 1500},
    "emcee": {"walkers": 32, "steps": 1800, "burn_in": 300},  # about 200 effective samples
}


def simulated_sensor(chain, rng, n=80, noise=5e-5, missing=()):
    """A sensor table from random configurations: known zero-offsets, no other effect."""
    q = rng.uniform(np.maximum(chain.lower, -2.0), np.minimum(chain.upper, 2.0), (n, chain.n_joints))
    truth = rng.normal(0.0, np.radians(0.4), chain.n_joints)
    sensor = Sensor(
        "laser_tracker",
        "laser_tracker",
        looking_at(rng.uniform([1.2, -0.5, 0.6], [2.0, 0.5, 1.5]), [0, 0, 0.6]),
        noise,
        np.array([-0.1, 0.0, 0.02]),
    )
    xyz = measure(chain, TrueRobot(zero_offsets=truth), sensor, q, rng)
    xyz[list(missing)] = np.nan
    table = pd.DataFrame(
        {"set": "optimization", "pose": np.arange(n, dtype=np.int64), "solution": np.zeros(n, dtype=np.int64)}
    )
    for j in range(chain.n_joints):
        table[f"q{j + 1}"] = q[:, j]
    table[["x", "y", "z"]] = xyz
    spec = {"kind": "laser_tracker", "marker": sensor.marker, "noise": noise}
    return sensor_data("laser_tracker", spec, table, chain.n_joints, "simulated.parquet"), truth


def fitted(chain, sensor, methods=("default",), seed=0):
    registration = fit.register(chain, sensor)
    model, analysis, excluded = fit.build_model(chain, sensor, registration.t_nr)
    laplace = LaplaceReport.of(laplace_report(laplace_fit(model), analysis, excluded))
    samples, reports = {}, {}
    for method in methods:
        chains = sample(model, laplace, method, FAST[method], np.random.default_rng(seed))
        samples[method] = samples_frame(chains)
        reports[method] = sampler_diagnostics(chains, 1.0)
    return laplace, samples, reports


def test_intervals_cover_the_truth_about_95_percent(iiwa):
    """Simulation-based calibration of the 95 % intervals: 24 campaigns x 6 identifiable offsets."""
    covered, total, z2 = 0, 0, 0.0
    for seed in range(24):
        rng = np.random.default_rng(1000 + seed)
        sensor, truth = simulated_sensor(iiwa, rng)
        laplace, samples, _ = fitted(iiwa, sensor, seed=seed)
        summary = posterior_summary(samples["default"], laplace)
        for j in range(1, 7):
            row = summary.loc[f"zero_offsets.q{j + 1}"]
            covered += bool(row["q2.5"] <= truth[j] <= row["q97.5"])
            z2 += ((row["mean"] - truth[j]) / row["std"]) ** 2
            total += 1
    # binomial(144, 0.95): mean 136.8, sd 2.6; MCMC quantiles add a little noise. Intervals too
    # narrow fail the first bound; too wide, the chi-square of the standardised errors (which
    # would fall far below its 144 degrees of freedom)
    assert 0.89 <= covered / total, f"{covered} of {total} intervals cover the truth"
    assert stats.chi2(total).ppf(0.005) < z2 < stats.chi2(total).ppf(0.995), f"chi-square {z2:.1f} of {total}"


def test_samplers_agree_and_unseen_points_are_excluded(iiwa, monkeypatch):
    rng = np.random.default_rng(5)
    sensor, _ = simulated_sensor(iiwa, rng, missing=(3, 17))
    laplace, samples, reports = fitted(iiwa, sensor, methods=("default", "emcee", "paper"))
    assert laplace.marker_not_seen_rows == (3, 17)
    assert laplace.held == {"zero_offsets.q1": 0.0}
    table = cross_check(samples, reports, laplace, tolerance=4.0, max_rhat=1.1, min_ess=100, floor=0.1)
    assert {"z_default", "z_emcee", "z_laplace", "z_paper"} <= set(table.columns)
    assert table["checked_emcee"].all() and table["checked_laplace"].all()
    assert (table.loc[table["checked_paper"], "z_paper"].abs() <= 4.0).all()
    assert not table["disagrees_emcee"].any() and (table["disagreement"] == "").all()
    assert disagreeing(table) == {}
    # a method shifted by several posterior std is caught, marked on its parameter and nowhere
    # else, and the table comes back (the campaign's report is made anyway)
    shifted = samples["emcee"].copy()
    shifted["zero_offsets.q3"] += 5 * shifted["zero_offsets.q3"].std()
    marked = cross_check(
        {**samples, "emcee": shifted}, reports, laplace, tolerance=4.0, max_rhat=1.1, min_ess=100, floor=0.1
    )
    assert marked.loc[marked["disagrees_emcee"], "parameter"].tolist() == ["zero_offsets.q3"]
    assert marked.set_index("parameter").loc["zero_offsets.q3", "z_emcee"] > 4.0
    assert disagreeing(marked) == {"zero_offsets.q3": ["emcee"]}
    assert [o[:3] for o in marked.attrs["disagreements"]] == [("zero_offsets.q3", "emcee", "default")]
    # as cross_check.csv holds it: the empty marks come back as NaN, the disagreement as written
    written = marked.astype({"disagreement": object}).replace("", np.nan)
    assert disagreeing(written) == {"zero_offsets.q3": ["emcee"]}
    # a sampler without diagnostics is shown, not checked: its shift is no disagreement
    unreported = cross_check(
        {**samples, "emcee": shifted},
        {"paper": reports["paper"]},
        laplace,
        tolerance=4.0,
        max_rhat=1.1,
        min_ess=100,
        floor=0.1,
    )
    assert not unreported["checked_emcee"].any() and disagreeing(unreported) == {}
    # the moments come from the samplers' own reports where these describe the samples (the
    # shifted emcee samples above were checked by their own), and are the samples' to the bit
    slow = []
    monkeypatch.setattr(cross_check_module.diagnostics, "moments", lambda chains: slow.append(1) or moments(chains))
    from_reports = cross_check(samples, reports, laplace, tolerance=4.0, max_rhat=1.1, min_ess=100, floor=0.1)
    assert slow == []
    without = {method: {k: v for k, v in report.items() if k != "parameters"} for method, report in reports.items()}
    from_samples = cross_check(samples, without, laplace, tolerance=4.0, max_rhat=1.1, min_ess=100, floor=0.1)
    assert len(slow) == 3
    pd.testing.assert_frame_equal(from_reports, from_samples, check_exact=True)


def test_laplace_and_mcmc_sigma_match_the_noise(iiwa):
    rng = np.random.default_rng(11)
    sensor, _ = simulated_sensor(iiwa, rng, n=150, noise=3e-5)
    laplace, samples, _ = fitted(iiwa, sensor)
    sigma = samples["default"]["noise.sigma"]
    assert sigma.mean() == pytest.approx(3e-5, rel=0.15)
    assert laplace.sigma_mean == pytest.approx(sigma.mean(), rel=0.03)
    assert laplace.sigma_std == pytest.approx(sigma.std(), rel=0.25)


def test_kuka_twin_identifiable_offsets_recovered_within_uncertainty():
    """The bundled twin (its unmodelled marker placement, drift, compliance and link errors
    included): each identifiable zero-offset within three posterior std of what the paper's model
    can recover, joint 1 held and reported as such. What it can recover: a drifting offset at the
    optimization set's mean time, and joint 7 turned by the marker's error about the flange axis
    (the paper's sensors differ there by 0.33 deg, which it puts down to the markers' mounting), and
    each joint turned by the link errors' turn about its own axis (`link_turns`)."""
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-twin", repo_root=REPO)
    truth = json.loads((REPO / "data" / "truth" / "kuka-twin.json").read_text())
    rate = np.radians(truth["effects"]["drift"]["zero_offset_rate_deg_per_hour"]) / 3600.0
    turns = {}  # rad: the marker's error about the flange axis, seen as a joint-7 offset
    for name, sensor in campaign.sensors.items():
        times = sensor.table.loc[sensor.set_mask("optimization"), "time"]
        elapsed = (times - sensor.table["time"].iloc[0]).dt.total_seconds().mean()
        marker, error = sensor.marker, np.array(truth["sensors"][name]["marker_error_m"])
        turns[name] = (marker[0] * error[1] - marker[1] * error[0]) / (marker[0] ** 2 + marker[1] ** 2)
        recoverable = (
            np.radians(truth["zero_offsets_deg"])
            + rate * elapsed
            + np.eye(7)[6] * turns[name]
            + link_turns(campaign.chain, scenario.robot_from_truth(truth).link_motions)
        )
        laplace, samples, _ = fitted(campaign.chain, sensor)
        summary = posterior_summary(samples["default"], laplace)
        assert summary.loc["zero_offsets.q1", "status"].startswith("held")
        for j in range(1, 7):
            row = summary.loc[f"zero_offsets.q{j + 1}"]
            assert abs(row["mean"] - recoverable[j]) < 3 * row["std"], (
                name,
                j + 1,
                row["mean"],
                recoverable[j],
                row["std"],
            )
        assert 0.7e-3 < summary.loc["noise.sigma", "mean"] < 0.95e-3  # the paper's size
    # the laser tracker's marker error shows as a joint-7 offset the truth does not have, as in the paper
    assert np.degrees(turns["laser_tracker"]) == pytest.approx(0.327, abs=0.001) and turns["motion_capture"] == 0.0


def test_remastering_file_and_tables(iiwa):
    from remaster.reporting import tables

    rng = np.random.default_rng(2)
    sensor, truth = simulated_sensor(iiwa, rng)
    laplace, samples, _ = fitted(iiwa, sensor)
    summary = posterior_summary(samples["default"], laplace)
    remaster = remastering(summary.reset_index(), iiwa.joint_names, "sim", "laser_tracker")
    assert remaster["joints"][0]["status"].startswith("held") and remaster["joints"][0]["std_deg"] is None
    for j in range(1, 7):
        entry = remaster["joints"][j]
        assert entry["correction_deg"] == pytest.approx(np.degrees(summary.loc[f"zero_offsets.q{j + 1}", "mean"]))
        low, high = entry["interval_95_deg"]
        assert low < entry["correction_deg"] < high
    table = tables.zero_offsets_table({"laser_tracker": summary, "motion_capture": summary})
    assert list(table.columns)[1].startswith("Motion Capture")  # the paper's column order
    assert table.iloc[0, 1] == tables.HELD and len(table) == 7
    other = tables.registration_params_table({"laser_tracker": summary})
    assert other["Parameter"].tolist() == [
        "x (mm)",
        "y (mm)",
        "z (mm)",
        "sigma (mm)",
        "alpha (deg)",
        "beta (deg)",
        "gamma (deg)",
    ]
    assert other.loc[3, "Laser Tracker MLE"] == pytest.approx(summary.loc["noise.sigma", "mean"] * 1e3)


def test_same_seed_same_samples(iiwa):
    sensor, _ = simulated_sensor(iiwa, np.random.default_rng(9))
    first = fitted(iiwa, sensor, methods=("default", "emcee"), seed=4)[1]
    second = fitted(iiwa, sensor, methods=("default", "emcee"), seed=4)[1]
    for method in first:
        pd.testing.assert_frame_equal(first[method], second[method])


def test_gross_error_is_flagged_listed_and_left_out(iiwa):
    """A laser tracker re-acquisition glitch of 4 mm on one point of a clean campaign."""
    from remaster.campaigns.campaign import sensor_data as rebuild

    sensor, truth = simulated_sensor(iiwa, np.random.default_rng(21), noise=2e-4)
    registration = fit.register(iiwa, sensor)
    clean_model, _, _ = fit.build_model(iiwa, sensor, registration.t_nr)
    assert fit.flag_outliers(clean_model, alpha=0.01).size == 0  # nothing flagged on clean data
    table = sensor.table.copy()
    table.loc[37, "y"] += 4e-3
    glitched = rebuild(
        "laser_tracker", {"kind": "laser_tracker", "marker": sensor.marker, "noise": 2e-4}, table, 7, "glitch.parquet"
    )
    model, _, _ = fit.build_model(iiwa, glitched, registration.t_nr)
    outliers = fit.flag_outliers(model, alpha=0.01)
    np.testing.assert_array_equal(outliers, [37])
    robust, analysis, excluded = fit.build_model(iiwa, glitched, registration.t_nr, exclude=outliers)
    assert 37 not in robust.data.rows and robust.n_points == model.n_points - 1
    report = laplace_report(laplace_fit(robust), analysis, excluded, outliers, robust)
    assert report["excluded_rows_outliers"] == [37] and report["points_fitted"] == robust.n_points
    offsets = np.array(report["theta_map"][6:])
    std = np.array(report["std"][6:])
    assert np.all(np.abs(offsets - truth[1:]) < 4 * std)  # the fit without the glitch is unbiased
    assert report["sigma_map"] < 3e-4


def test_a_laplace_report_missing_a_key_names_the_file_and_the_key(iiwa, rng, tmp_path):
    """The later stages read laplace.json as a typed `LaplaceReport`: a complete report comes back
    exactly, and a key that is not there is named with its file."""
    sensor, _ = simulated_sensor(iiwa, rng, missing=(4,))
    model, analysis, excluded = fit.build_model(iiwa, sensor, fit.register(iiwa, sensor).t_nr)
    content = laplace_report(laplace_fit(model), analysis, excluded, (7, 2), model)
    path = tmp_path / "laplace.json"
    files.write_json(path, content)
    report = LaplaceReport.read(path)
    assert report.names == model.names and report.parameters == model.all_names
    assert np.array_equal(report.covariance, content["covariance"]) and report.sigma_map == content["sigma_map"]
    assert report.held == {"zero_offsets.q1": 0.0} and report.null_directions
    assert report.outlier_rows == (7, 2) and report.marker_not_seen_rows == (4,)
    assert report.points_fitted == model.n_points
    start, covariance = report.start()
    assert np.array_equal(start[:-1], content["theta_map"]) and covariance[-1, -1] == content["sigma_std"] ** 2
    del content["identifiability"]["held_at_controller_value"]
    files.write_json(path, content)
    with pytest.raises(InputError, match=r"laplace.json: identifiability/held_at_controller_value: missing"):
        LaplaceReport.read(path)


def test_a_registration_report_comes_back_typed_and_a_missing_key_is_named(iiwa, rng, tmp_path):
    """registration.json is read back as the `Registration` that wrote it (every later stage
    takes its t_nr); a key that is not there is named with its file."""
    sensor, _ = simulated_sensor(iiwa, rng)
    registered = fit.register(iiwa, sensor)
    path = tmp_path / "registration.json"
    files.write_json(path, registered.report())
    read = fit.Registration.read(path)
    assert np.array_equal(read.t_nr, registered.t_nr) and np.array_equal(read.kabsch_t_nr, registered.kabsch_t_nr)
    assert read.rows == registered.rows and read.three_point_rms == pytest.approx(registered.three_point_rms, rel=1e-12)
    content = registered.report()
    del content["T_NR"]
    files.write_json(path, content)
    with pytest.raises(InputError, match=r"registration.json: T_NR: missing in the registration report"):
        fit.Registration.read(path)


def test_many_log_posteriors_are_the_same_a_slice_at_a_time(iiwa, rng, monkeypatch):
    """A sampler's batch is evaluated a slice of vectors at a time so that memory does not grow
    with the campaign: the same numbers as one stacked call and as one vector at a time."""
    sensor, _ = simulated_sensor(iiwa, rng)
    model, _, _ = fit.build_model(iiwa, sensor, fit.register(iiwa, sensor).t_nr)
    target = PosteriorTarget(model)
    thetas = np.column_stack([rng.normal(0.0, 1e-4, (25, len(model.names))), rng.uniform(1e-4, 1e-3, 25)])
    whole = target.log_prob_many(thetas)
    monkeypatch.setattr(
        posterior_targets, "POINTS_PER_CALL", 4 * model.n_points
    )  # 4 vectors a slice, the last one short
    assert np.array_equal(target.log_prob_many(thetas), whole)
    assert whole[3] == target.log_prob(thetas[3]) and target.log_prob_many(thetas[:0]).shape == (0,)


@pytest.mark.parametrize("rows", [40, 600], ids=["summed over the rows", "expanded in the zero-offsets"])
def test_the_compiled_walk_is_the_python_walk_to_the_bit(iiwa, rng, rows):
    """The paper's model steps its random walks compiled (`BlockModel.metropolis_block`): the
    same draws give the same chain as the Python loop over its log_prob, bit for bit, for the
    paper's sampler and the adaptive one, with the sum of squares over the rows or expanded (a
    campaign of many rows); a proposal with sigma <= 0 is rejected, not an error."""
    from remaster.inference.sampling.metropolis import metropolis_adaptive, metropolis_paper
    from remaster.inference.sampling.random_walk import _Progress, _start, _walk
    from remaster.inference.sampling.target import CallableTarget, SamplingError

    sensor, _ = simulated_sensor(iiwa, rng, n=rows)
    model, _, _ = fit.build_model(iiwa, sensor, fit.register(iiwa, sensor).t_nr)
    assert (model._expansion()[0].shape[0] > 0) == (rows == 600)
    compiled = PosteriorTarget(model)
    python = CallableTarget(compiled.names, compiled.scale, compiled.log_prob_many, compiled.log_prob)
    assert compiled.walk_block is not None and getattr(python, "walk_block", None) is None
    start = np.append(np.zeros(len(model.names)), 2e-5)  # sigma near 0: some proposals fall below it
    runs = [
        metropolis_paper(
            t, np.random.default_rng(3), start, n_samples=9000, burn_in=5000, half_width=0.05, trace_every=7
        )
        for t in (compiled, python)
    ]
    assert np.array_equal(runs[0].samples, runs[1].samples) and np.array_equal(runs[0].log_prob, runs[1].log_prob)
    assert np.array_equal(runs[0].settings["burn_in_trace"], runs[1].settings["burn_in_trace"])
    assert runs[0].acceptance_rate == runs[1].acceptance_rate and 0 < runs[0].acceptance_rate < 1
    adaptive = [
        metropolis_adaptive(t, np.random.default_rng(4), start, n_samples=6000, burn_in=2000)
        for t in (compiled, python)
    ]
    assert np.array_equal(adaptive[0].samples, adaptive[1].samples)
    # a NaN log-posterior stops the compiled block where it occurs, as it stops the Python loop
    steps = np.zeros((6, len(start)))
    steps[3, 0] = np.nan
    states, _, _, nan_at = model.metropolis_block(start, compiled.log_prob(start), steps, np.zeros(6))
    assert nan_at == 3 and np.isfinite(states[:3]).all()
    with pytest.raises(SamplingError, match="log_prob returned NaN"):
        _walk(
            compiled,
            np.random.default_rng(0),
            _start(compiled, start),
            10,
            lambda rng, m: np.where(np.arange(m)[:, None] == 3, np.nan, 0.0) * np.ones((m, len(start))),
            False,
            _Progress(None, 10),
        )


def test_points_no_frame_fits_are_named_by_the_sensor_file_and_rows(iiwa):
    """A sensor table built in code (the reader refuses measured points on one line, a program need
    not): the registration's refusal names the campaign's sensor file, the reason and the rows."""
    from types import SimpleNamespace

    from remaster.campaigns.campaign import SensorData

    rng = np.random.default_rng(3)
    table = pd.DataFrame({"set": ["optimization"] * 6, "pose": np.arange(6), "solution": np.zeros(6, int)})
    for j, column in enumerate(rng.uniform(-1.0, 1.0, (7, 6))):
        table[f"q{j + 1}"] = column
    table["x"], table["y"], table["z"] = np.linspace(0.5, 1.0, 6), 0.2, 0.3  # on one line
    sensor = SensorData("laser_tracker", "laser_tracker", np.array([0.0, 0.0, 0.05]), 3e-5, table)
    campaign = SimpleNamespace(name="lined", chain=iiwa, sensors={"laser_tracker": sensor})
    with pytest.raises(InputError, match=r"^lined/laser_tracker.parquet: the optimization set cannot register") as info:
        fit.registration_stage(campaign, "laser_tracker")
    assert "every measured point lies on one line" in str(info.value) and "rows 0, 1, 2, 3, 4, 5" in str(info.value)
