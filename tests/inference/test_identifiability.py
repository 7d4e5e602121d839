"""One identifiability rule for the analysis before the fit and the Laplace fit: a direction the
data cannot see (singular value) or a zero-offset they determine no better than the controller's
marks (Laplace std at the fit's sigma over STD_BOUND) is held at the controller's value and named,
with its reason, in laplace.json, the summary and the certificate's corrections."""

import json
import math

import numpy as np
import pytest

import remaster
from remaster import api, files
from remaster.campaigns import arm_kinds, folders, scenario
from remaster.inference import fit, identifiability
from remaster.inference.blocks import paper_model
from remaster.inference.laplace_report import LaplaceReport, laplace_fit, laplace_report
from remaster.inference.least_squares import RCOND, undetermined_directions
from remaster.inference.model import display_scale
from remaster.inference.posterior_summary import mode_summary, remastering

from ..conftest import REPO
from .test_fit import simulated_sensor
from .test_fits_finish import sensor_table

Q7 = "zero_offsets.q7"
# a marker 3 mm off the flange axis on a stalk, measured with the paper's size of sigma (its
# model error and the sensor's noise together: the bundled twin's fit has 0.7 to 0.95 mm)
OFF_AXIS_MARKER = [0.003, 0.0, 0.080]
PAPER_SIGMA = 5e-4


def off_axis_campaign(tmp_path, distance=OFF_AXIS_MARKER[0], noise=PAPER_SIGMA):
    """A campaign folder of a laser tracker whose marker sits `distance` (m) off joint 7's axis."""
    tracker = {**arm_kinds.TRACKER, "marker": [distance, 0.0, OFF_AXIS_MARKER[2]], "noise": noise}
    spec = arm_kinds.iiwa_scenario("marker-off-axis", seed=13, sensors={"laser_tracker": tracker})
    out = scenario.simulate(spec, arm_kinds.chain_of(spec, REPO))
    return folders.read_campaign(folders.write_campaign(tmp_path / spec["name"], out.metadata, out.tables), REPO)


def test_the_std_rule_holds_the_loosest_zero_offset_and_narrows_the_rest():
    """Synthetic Jacobian (step units): q7 nearly 0.9 x q6's column, q5 a short one, a
    registration parameter shorter still. At sigma the Laplace stds (the fit's own formula) of q5,
    q6 and q7 and the registration's are over the bound: q7 (the widest) is held, which leaves q6
    determined to 1 % of the bound; q5 stays over it and is held too; the registration parameter is
    never held by the bound (it has no marks). At half that sigma nothing is held."""
    rng = np.random.default_rng(11)
    names = ["registration.x", "zero_offsets.q5", "zero_offsets.q6", Q7]
    scale = np.array([display_scale(n) for n in names])
    steps = rng.normal(size=(60, 4))
    steps[:, 0] *= 5e-4
    steps[:, 1] *= 0.01
    steps[:, 3] = 0.9 * steps[:, 2] + 0.01 * rng.normal(size=60)
    jacobian = steps / scale
    sigma = 0.1 * identifiability.STD_BOUND / display_scale(Q7)  # m, as if per deg of column
    bound = identifiability.STD_BOUND
    laplace_std = np.sqrt(np.diag(sigma**2 * np.linalg.inv(jacobian.T @ jacobian)))
    assert np.all(laplace_std[1:] > bound) and laplace_std[3] == laplace_std[1:].max()
    found = identifiability.loose_zero_offsets(jacobian, names, scale, sigma)
    assert list(found) == [Q7, "zero_offsets.q5"]
    assert found[Q7][1] == pytest.approx(laplace_std[3])
    assert found[Q7][0][Q7] == 1.0 and found[Q7][0]["zero_offsets.q6"] == pytest.approx(-0.9, abs=0.02)
    free = [0, 2]  # what is left: q6 now well inside the bound
    left = np.sqrt(np.diag(sigma**2 * np.linalg.inv(jacobian[:, free].T @ jacobian[:, free])))
    assert left[1] < 0.02 * bound
    assert identifiability.loose_zero_offsets(jacobian, names, scale, sigma / 2) == {}


def test_a_marker_a_few_mm_off_the_last_axis_holds_and_names_joint_7(iiwa):
    """80 random configurations, marker 3 mm off joint 7's axis, the paper's sigma: the
    singular-value test alone lets q7 through with a Laplace std of degrees (what the fit reported
    before: a correction no better than the controller's marks). The analysis (at the fit's
    optimum and sigma) holds it and names it with its reason; the Laplace fit of the rest finishes
    within the bound; the summary, the remastering file and the statements say it."""
    rng = np.random.default_rng(3)
    q = rng.uniform(np.maximum(iiwa.lower, -2.0), np.minimum(iiwa.upper, 2.0), (80, 7))
    sensor = sensor_table(iiwa, q, [0.003, 0.0, 0.05], rng.normal(0.0, np.radians(0.3), 7), rng, noise=PAPER_SIGMA)
    registration = fit.register(iiwa, sensor)
    full = paper_model(iiwa, q, sensor.table[["x", "y", "z"]].to_numpy(), sensor.marker, registration.t_nr)
    structural = identifiability.analyse(full)
    assert set(structural.held) == {"zero_offsets.q1"}  # the premise: visible to the singular values
    old = laplace_fit(paper_model(iiwa, q, full.measured, sensor.marker, registration.t_nr, structural.held))
    assert old.std[old.names.index(Q7)] > 2 * identifiability.STD_BOUND

    model, analysis, excluded = fit.build_model(iiwa, sensor, registration.t_nr)
    assert set(analysis.held) == {"zero_offsets.q1", Q7} and Q7 not in model.names
    assert analysis.sigma == pytest.approx(old.sigma_map, rel=0.05)
    assert analysis.loose[Q7] == pytest.approx(old.std[old.names.index(Q7)], rel=0.01)
    result = laplace_fit(model)  # no NotIdentifiable
    zero = [i for i, n in enumerate(result.names) if n.startswith("zero_offsets.")]
    assert np.all(result.std[zero] < identifiability.STD_BOUND)
    laplace = LaplaceReport.of(json.loads(json.dumps(laplace_report(result, analysis, excluded, (), model))))
    assert laplace.held_reasons == {
        "zero_offsets.q1": "not identifiable",
        Q7: f"not determined: std {math.degrees(analysis.loose[Q7]):.3g} deg > 0.5 deg",
    }
    statement = next(s for s in laplace.held_statements if s.startswith(Q7))
    assert "no better than the controller's marks (0.5 deg)" in statement
    summary = mode_summary(laplace)
    assert summary.loc[Q7, "status"].startswith("held: not determined")
    assert summary.loc["zero_offsets.q1", "status"] == "held: not identifiable"
    joints = remastering(summary, iiwa.joint_names, "sim", "laser_tracker")["joints"]
    assert joints[6]["std_deg"] is None and joints[6]["correction_deg"] == 0.0
    assert joints[6]["status"].startswith("held: not determined")


def test_a_normal_campaigns_held_set_is_unchanged(iiwa):
    """A marker 100 mm off the flange axis (the twin's): joint 1 alone held, for the singular
    value's reason, and every zero-offset's std far inside the bound; the bundled twin's sensors
    too."""
    sensor, _ = simulated_sensor(iiwa, np.random.default_rng(5))
    _, analysis, _ = fit.build_model(iiwa, sensor, fit.register(iiwa, sensor).t_nr)
    assert analysis.held == {"zero_offsets.q1": 0.0} and analysis.loose == {}
    assert analysis.reasons() == {"zero_offsets.q1": "not identifiable"}
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-twin", repo_root=REPO)
    for sensor in campaign.sensors.values():
        model, analysis, _ = fit.build_model(campaign.chain, sensor, fit.register(campaign.chain, sensor).t_nr)
        assert analysis.held == {"zero_offsets.q1": 0.0}
        result = laplace_fit(model)
        assert result.std[result.names.index(Q7)] < 0.2 * identifiability.STD_BOUND


def test_the_analysis_and_the_fit_share_one_singular_value_test():
    """The fit's test is the analysis's: one function, one threshold (the analysis at twice it)."""
    assert undetermined_directions is identifiability.undetermined_directions
    assert RCOND is identifiability.RCOND and identifiability.RELATIVE_THRESHOLD == 2 * RCOND


def test_a_campaign_with_its_marker_3_mm_off_axis_is_calibrated_with_joint_7_held(tmp_path):
    """Through the stages of the certificate's inputs (`remaster.calibrate`: prepare, loop closure,
    workspace, acceptance): no exception, joint 7 held in the zero-offset fit and the loop's refit,
    named with its reason, and the rest of the zero-offsets estimated."""
    campaign = off_axis_campaign(tmp_path)
    _, content = fit.prepare_stage(campaign, "laser_tracker", api.settings()["outliers"])
    laplace = LaplaceReport.of(json.loads(json.dumps(files.plain(content))))
    assert set(laplace.held) == {"zero_offsets.q1", Q7}
    assert laplace.held_reasons[Q7].startswith("not determined: std")
    assert content["identifiability"]["not_determined_std_deg"][Q7] > 0.5
    calibration = remaster.calibrate(campaign, "laser_tracker", seed=0)
    status = calibration.summary["status"]
    assert status[Q7].startswith("held: not determined") and status["zero_offsets.q1"] == "held: not identifiable"
    assert (status[[f"zero_offsets.q{j}" for j in range(2, 7)]] == "estimated").all()
    refit = calibration.loop.report.parameters.set_index("parameter")
    assert refit.loc[Q7, "status"].startswith("held") and refit.loc[Q7, "mean"] == 0.0
    assert calibration.acceptance.verdict in ("pass", "fail", "not tested")
