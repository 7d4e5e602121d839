"""A validation set that cannot test, and an optimization set too thin to determine the zero-offsets:
the acceptance test's count of distinct configurations (`acceptance.distinct_configurations`,
`configurations_needed`), a simulated campaign whose validation set is one configuration measured
151 times under 32 pose labels, or three configurations, against the same campaign's normal
validation set, and what the certificate makes of each. Cheap: the paper's Laplace fit stands in
for the loop closure (a report whose refit is the paper model's mode, closed at the noise), so no
loop closure runs."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from remaster import api, files, spatial
from remaster.campaigns import folders, scenario
from remaster.campaigns.arm_kinds import TRACKER, chain_of, iiwa_scenario
from remaster.errors import InputError
from remaster.evaluation import acceptance, budget
from remaster.evaluation.acceptance import CANNOT_TEST, PASS, Acceptance
from remaster.inference import fit
from remaster.inference.laplace_report import LaplaceReport
from remaster.loop.result import LoopResults
from remaster.reporting import certificate
from remaster.units import DEG, MM

from ..conftest import REPO, loop_report, validated_config
from ..reporting.test_certificate import SUMMARY, _inputs

NOISE = TRACKER["noise"]  # m per axis
# ISO 9283's RP = l_bar + 3 S_l of isotropic Gaussian noise sigma per axis: |e| is chi with 3 degrees
# of freedom, mean sigma sqrt(8 / pi), std sigma sqrt(3 - 8 / pi)
RP_OF_NOISE = NOISE * (np.sqrt(8 / np.pi) + 3 * np.sqrt(3 - 8 / np.pi))


# --------------------------------------------------------------------------- the rule


def test_rows_within_a_tenth_of_a_degree_in_every_joint_are_one_configuration():
    rng = np.random.default_rng(1)
    base = rng.uniform(-1.0, 1.0, 7)
    jitter = base + rng.uniform(-0.02, 0.02, (50, 7)) * DEG  # one configuration, encoder jitter
    assert set(acceptance.distinct_configurations(jitter)) == {0}
    # another IK solution of the same target: the marker at one point, the joints far apart
    other = base + np.array([0.0, 0.0, 30.0, 0.0, 0.0, 0.0, 0.0]) * DEG
    apart = base + np.array([0.0, 0.15, 0.0, 0.0, 0.0, 0.0, 0.0]) * DEG  # 0.15 deg in one joint
    labels = acceptance.distinct_configurations(np.vstack([jitter, other[None], apart[None], jitter[:3]]))
    assert labels.max() + 1 == 3 and labels[50] == 1 and labels[51] == 2 and (labels[52:] == 0).all()
    # a slow sweep (0.06 deg a row over 1.2 deg) is not chained into one configuration
    sweep = base + np.outer(np.arange(21) * 0.06 * DEG, np.eye(7)[1])
    assert acceptance.distinct_configurations(sweep).max() + 1 == 11
    # three numbers per configuration against the paper model's free parameters, never fewer than 3
    assert [acceptance.configurations_needed(p) for p in (3, 9, 12, 13)] == [3, 3, 4, 5]


# --------------------------------------------------------------------------- a simulated campaign


def _paper_as_loop(laplace: LaplaceReport):
    """A loop closure report whose final model is the paper's (registration and zero-offsets, its
    Laplace mode and std), closed at the noise: the acceptance test's claim is then the paper fit's."""
    rows = []
    for name in laplace.parameters:
        held = name in laplace.held
        value = laplace.held[name] if held else float(laplace.theta_map[laplace.names.index(name)])
        rows.append(
            {"parameter": name, "block": name.split(".")[0], "mean": value, "status": "held" if held else "estimated"}
        )
    mode = {
        "names": list(laplace.names),
        "theta": laplace.theta_map.tolist(),
        "std": laplace.std.tolist(),
        "sigma_mm": laplace.sigma_map / MM,
    }
    closure = {"closed": True, "verdict": "closed", "rounds": [{"closed": True, "structured_mm": 0.0}]}
    return loop_report(rows, closure=closure, refit={"parameters": rows, "mode": mode})


@pytest.fixture(scope="module")
def simulated():
    spec = iiwa_scenario("thin", seed=31)
    chain = chain_of(spec, REPO)
    return spec, scenario.simulate(spec, chain)


def _sensor_points(simulated_campaign, rows) -> np.ndarray:
    """The true marker positions (len(rows), 3) m at table rows, in the tracker's frame."""
    truth = simulated_campaign.truth["sensors"]["laser_tracker"]
    points = np.array(truth["true_marker_positions_robot_frame_m"])[rows]
    return spatial.transform_points(np.array(truth["T_NR"]), points)


def _repeated(table: pd.DataFrame, rows, times: int, rng: np.random.Generator) -> pd.DataFrame:
    """Table rows `rows` each measured `times` times (joint readings as they are, the tracker's noise
    drawn anew), under stale pose labels: pose k mod 32, solution k div 32."""
    out = table.loc[np.repeat(rows, times)].reset_index(drop=True)
    out["pose"], out["solution"] = np.arange(len(out)) % 32, np.arange(len(out)) // 32
    return out


def _campaign(tmp: Path, spec: dict, simulated_campaign, table: pd.DataFrame):
    metadata, tables = simulated_campaign.metadata, {"laser_tracker": table.reset_index(drop=True)}
    folder = tmp / spec["name"]
    folders.write_campaign(folder, metadata, tables)
    return folders.read_campaign(folder, repo_root=REPO)


def _accepted(campaign) -> tuple[Acceptance, LaplaceReport]:
    config = validated_config(files.read_yaml(REPO / "config.yaml"))
    registered = fit.registration_stage(campaign, "laser_tracker")
    laplace = LaplaceReport.of(fit.laplace_stage(campaign, "laser_tracker", registered, api.settings()["outliers"]))
    result = acceptance.acceptance_stage(
        campaign,
        "laser_tracker",
        registered.t_nr,
        laplace,
        None,
        LoopResults(_paper_as_loop(laplace), None, None),
        np.random.default_rng(5),
        config["acceptance"],
    )
    return result, laplace


def _with_validation(simulated, tmp_path, configurations: int, times: int) -> Acceptance:
    """The campaign's optimization set and, as its validation set, its first `configurations` measured
    validation configurations (different poses) each measured `times` times."""
    spec, sim = simulated
    table = sim.tables["laser_tracker"]
    measured = table["x"].notna().to_numpy()
    validation = table[(table["set"] == "validation").to_numpy() & measured]
    chosen = validation.drop_duplicates("pose").index[:configurations].to_numpy()
    rng = np.random.default_rng(configurations)
    repeats = _repeated(table, chosen, times, rng)
    repeats[["x", "y", "z"]] = np.repeat(_sensor_points(sim, chosen), times, axis=0) + NOISE * rng.standard_normal(
        (len(repeats), 3)
    )
    result, _ = _accepted(_campaign(tmp_path, spec, sim, pd.concat([table[table["set"] == "optimization"], repeats])))
    return result


def test_a_normal_validation_set_still_passes(simulated, tmp_path):
    spec, sim = simulated
    result, _ = _accepted(_campaign(tmp_path, spec, sim, sim.tables["laser_tracker"]))
    counted = result.configurations
    assert result.verdict == PASS and result.diagnosis_text.startswith("pass: ")
    # its 4 poses' IK solutions are distinct configurations, each measured once
    assert counted["distinct"] == counted["rows"] == result.validation_rows and counted["tests"]
    assert counted["needed"] == 4 and counted["parameters"] == 12 and counted["repeats"] is None
    assert result.budget["validation_tests"] and not any("cannot test" in w for w in result.warnings)


def test_one_configuration_measured_151_times_cannot_test(simulated, tmp_path):
    result = _with_validation(simulated, tmp_path, 1, 151)
    assert result.verdict == CANNOT_TEST and not result.passed and result.diagnosis is None
    assert result.diagnosis_text == "cannot test: 1 distinct configuration of 151 validation rows (at least 4 needed)"
    # the check itself passes at the one configuration: the noise there is what the claim says
    assert result.checks["loop"]["passed"]
    flag = result.warnings[0]
    assert "gives no acceptance pass" in flag and "a check of the noise there, not of the calibration" in flag
    # ISO 9283 repeatability of the 151 cycles: the tracker's noise alone here
    repeats = result.configurations["repeats"]
    assert repeats["configurations"] == 1 and repeats["cycles"] == 151
    assert repeats["RP_max_mm"] == pytest.approx(RP_OF_NOISE / MM, rel=0.15)
    assert f"RP {repeats['RP_max_mm']:.2g} mm" in flag
    # the budget's share within U is said to check the noise, not the budget
    assert not result.budget["validation_tests"] and result.budget["validation_configurations"] == 1
    note = budget.budget_table({"laser_tracker": result}).set_index("Component").loc["validation rows within U (%)"]
    assert note["note"].startswith("not a check of the budget: 151 validation rows (1 distinct configurations)")
    # acceptance.json round-trips with its verdict and count
    again = Acceptance.read(result.write(tmp_path / "acceptance.json"))
    assert again == result and again.verdict == CANNOT_TEST


def test_three_configurations_cannot_test_a_seven_axis_calibration(simulated, tmp_path):
    result = _with_validation(simulated, tmp_path, 3, 50)
    assert result.verdict == CANNOT_TEST and not result.passed
    assert result.diagnosis_text == "cannot test: 3 distinct configurations of 150 validation rows (at least 4 needed)"
    repeats = result.configurations["repeats"]
    assert repeats["configurations"] == 3 and repeats["cycles_min"] == repeats["cycles_max"] == 50
    assert repeats["RP_mean_mm"] == pytest.approx(RP_OF_NOISE / MM, rel=0.15)


# --------------------------------------------------------------------------- the certificate


def _cannot_test(groups) -> Acceptance:
    """An acceptance.json of `_inputs`' validation rows (100-119, pose k // 2) counted into the
    configurations `groups` (20,): cannot test."""
    rows = list(range(100, 120))
    configurations = {
        "distinct": len(set(groups)),
        "rows": 20,
        "needed": 4,
        "parameters": 12,
        "tolerance_deg": 0.1,
        "tests": False,
        "table_rows": rows,
        "configuration_of_row": list(groups),
        "repeats": None,
    }
    text = f"cannot test: {len(set(groups))} distinct configurations of 20 validation rows (at least 4 needed)"
    checks = {m: {"passed": True, "p_value": 0.9} for m in ("loop", "paper")}
    return Acceptance(
        "laser_tracker",
        CANNOT_TEST,
        None,
        text,
        None,
        checks,
        0.01,
        0.95,
        10.0,
        100,
        20,
        (),
        (f"acceptance test {text}: ...",),
        configurations=configurations,
    )


def test_the_certificate_of_a_set_that_cannot_test_flags_it_and_never_passes():
    """One configuration under ten pose labels: no pass, a red flag first among the sensor's
    warnings, and no U of the mean (one cluster, not ten); two configurations: U from two clusters,
    k = t_0.975(1) = 12.7."""
    inputs = dataclasses.replace(_inputs(), acceptance=_cannot_test([0] * 20))
    cert = certificate.certificate(SUMMARY, {"laser_tracker": inputs})
    verdict = cert.verdicts.iloc[0]
    assert verdict["Acceptance"] == "cannot test: 1 distinct configurations of 20 validation rows (at least 4 needed)"
    assert np.isnan(verdict["U(After: mean) (mm)"]) and np.isnan(verdict["U(Before: mean) (mm)"])
    assert "U not determined" in cert.brief[0] and "acceptance cannot test" in cert.brief[0]
    assert cert.warnings[0].startswith("Laser Tracker: RED FLAG, no acceptance: acceptance test cannot test")
    assert sum("acceptance test cannot test" in w for w in cert.warnings) == 1  # said once
    assert "| pass |" not in certificate.to_markdown(cert)
    # two configurations, rows 100-109 and 110-119 (five poses each)
    two = certificate.certificate(
        SUMMARY, {"laser_tracker": dataclasses.replace(_inputs(), acceptance=_cannot_test([0] * 10 + [1] * 10))}
    )
    after = two.accuracy.set_index(["Where", "Model"]).loc[("validation set (measured)", "remastered zero-offsets")]
    errors = 1.0 + 0.1 * (np.arange(20) % 2) + 0.01 * np.arange(20)
    means = errors.reshape(2, 10).mean(axis=1)
    # CR2 with two equal clusters: u = |difference of the cluster means| / 2, k = t_0.975(1)
    assert after["k"] == pytest.approx(12.706, abs=1e-3)
    assert after["U(mean) (mm)"] == pytest.approx(12.706 * abs(means[1] - means[0]) / 2, rel=1e-3)


def test_pose_clusters_are_unchanged_where_each_configuration_is_of_one_pose():
    inputs = _inputs()
    plain = certificate.certificate(SUMMARY, {"laser_tracker": inputs}).accuracy
    counted = _cannot_test(list(range(20)))  # every row its own configuration: poses decide
    same = certificate.certificate(SUMMARY, {"laser_tracker": dataclasses.replace(inputs, acceptance=counted)}).accuracy
    pd.testing.assert_frame_equal(plain, same)


# --------------------------------------------------------------------------- a thin optimization set


def test_a_thin_optimization_set_is_refused_or_holds_what_it_cannot_determine(simulated, tmp_path):
    """One configuration measured 6 times: the campaign is refused with the reason (its points lie
    on one line), no traceback of a fit. Three configurations measured twice: the paper fit holds
    the zero-offsets those 9 numbers cannot tell apart, the certificate calls them not determined,
    and the acceptance test on the normal validation set does not pass the thin fit."""
    spec, sim = simulated
    table = sim.tables["laser_tracker"]
    measured = (table["set"] == "optimization").to_numpy() & table["x"].notna().to_numpy()
    first = np.flatnonzero(measured)[[0, 5, 10]]
    rng = np.random.default_rng(2)
    validation = table[table["set"] == "validation"]
    one = _repeated(table, first[:1], 6, rng)
    one[["x", "y", "z"]] = _sensor_points(sim, first[:1]) + NOISE * rng.standard_normal((6, 3))
    with pytest.raises(InputError, match="all lie on one line"):
        _campaign(tmp_path / "one", spec, sim, pd.concat([one, validation]))
    three = _repeated(table, first, 2, rng)
    three[["x", "y", "z"]] = np.repeat(_sensor_points(sim, first), 2, axis=0) + NOISE * rng.standard_normal((6, 3))
    result, laplace = _accepted(_campaign(tmp_path / "three", spec, sim, pd.concat([three, validation])))
    held = sorted(n for n in laplace.held if n.startswith("zero_offsets."))
    assert len(held) >= 3  # 12 parameters, 9 numbers (and the noise): some cannot be told apart
    assert result.verdict != PASS and not result.passed
    inputs = dataclasses.replace(_inputs(), laplace=laplace, acceptance=result)
    cert = certificate.certificate(SUMMARY, {"laser_tracker": inputs})
    names = ", ".join(n.split(".")[-1] for n in laplace.held if n.startswith("zero_offsets."))
    assert (
        f"not determined: the accuracy across the joint limits (the data did not reach there); the zero-offsets of {names}"
        in cert.brief[0]
    )
    assert not cert.verdicts.iloc[0]["Acceptance"].startswith("pass")
