"""The uncertainty budget by Monte Carlo: known answers of a closed-form claim (u per source, the
distance's 95th percentile), its coverage of rows it never fitted, and the table's rows."""

import dataclasses

import numpy as np
from scipy import stats

from remaster.evaluation import acceptance, budget
from remaster.evaluation.acceptance import Claim

from .test_acceptance import Translation

SIGMA, N_FIT, N_VALIDATION, DRAWS = 0.02e-3, 30, 40, 2000


def _claim(rng: np.random.Generator, declared: float = 0.0, effect: float = 0.0):
    """A translation fitted on N_FIT rows (exact posterior N(mean, sigma^2 / N_FIT I3), flat prior,
    sigma known) and validated on N_VALIDATION new rows; `effect`: a scale the model lacks (in both
    sets), `declared`: the model error per axis it declares. Returns (measured, claim)."""
    truth = rng.normal(0.0, 1e-3, 3)
    points_fit, points = rng.uniform(-0.5, 0.5, (N_FIT, 3)), rng.uniform(-0.5, 0.5, (N_VALIDATION, 3))
    fit = points_fit * (1 + effect) + truth + SIGMA * rng.standard_normal((N_FIT, 3))
    measured = points * (1 + effect) + truth + SIGMA * rng.standard_normal((N_VALIDATION, 3))
    mean = (fit - points_fit).mean(axis=0)
    theta = mean + SIGMA / np.sqrt(N_FIT) * rng.standard_normal((DRAWS, 3))
    model = Translation(points, measured)
    claim = Claim(model.predict(mean), model, theta, np.full(DRAWS, SIGMA), (), "exact posterior")
    return measured, dataclasses.replace(claim, instrument=np.full((N_VALIDATION, 3), SIGMA), declared=declared)


def test_each_source_and_the_distances_95th_percentile_have_their_known_values():
    measured, claim = _claim(np.random.default_rng(1))
    result = acceptance.claim_budget(measured, claim, np.random.default_rng(2), mpe=0.05e-3)
    u = {part["source"]: part["u_per_axis_mm"] for part in result["sources"]}
    assert set(u) == {acceptance.CALIBRATION, acceptance.NOISE}
    assert np.isclose(u[acceptance.CALIBRATION], SIGMA / np.sqrt(N_FIT) / 1e-3, rtol=0.05)
    assert np.isclose(u[acceptance.NOISE], SIGMA / 1e-3, rtol=0.03)
    assert np.isclose(sum(p["share_percent"] for p in result["sources"]), 100.0)
    combined = SIGMA * np.sqrt(1 + 1 / N_FIT)
    assert np.isclose(result["combined_u_per_axis_mm"], combined / 1e-3, rtol=0.03)
    # a 3-D Gaussian error: its distance's 95th percentile is u sqrt(chi2_3(0.95)) = 2.80 u
    assert np.isclose(result["U95_distance_mm"], combined * np.sqrt(stats.chi2.ppf(0.95, 3)) / 1e-3, rtol=0.03)
    assert result["U95_position_distance_mm"] < 0.3 * result["U95_distance_mm"]
    assert result["mpe_mm"] == 0.05


def test_the_budget_covers_rows_it_never_fitted_and_a_missing_effect_only_when_declared():
    """Over 200 campaigns of a correct model, 95 % of the validation rows lie within U; a model
    missing an effect falls short unless it declares the error it measured."""
    rng = np.random.default_rng(3)
    within = [acceptance.claim_budget(*_claim(rng), rng)["validation_within_U95"] for _ in range(200)]
    # each campaign's share moves with its posterior mean's error: the mean over campaigns is 95 %
    assert 0.94 <= np.mean(within) <= 0.96
    effect = 4e-4  # 0.1 mm at 0.25 m, several times the noise
    short = [acceptance.claim_budget(*_claim(rng, effect=effect), rng)["validation_within_U95"] for _ in range(50)]
    assert np.mean(short) < 0.6
    rms = effect * np.sqrt(1 / 12)  # the effect's RMS per axis over coordinates uniform on [-0.5, 0.5]
    declared = [
        acceptance.claim_budget(*_claim(rng, declared=rms, effect=effect), rng)["validation_within_U95"]
        for _ in range(50)
    ]
    assert np.mean(declared) >= 0.9


def test_the_table_gives_each_source_the_us_and_the_coverage_and_says_when_there_is_no_budget():
    measured, claim = _claim(np.random.default_rng(4), declared=0.01e-3)
    result = acceptance.claim_budget(measured, claim, np.random.default_rng(5))
    accepted = dataclasses.make_dataclass("Accepted", [("budget", object), ("diagnosis_text", str)])
    table = budget.budget_table(
        {
            "laser_tracker": accepted(result, ""),
            "motion_capture": accepted(None, "not tested: 2 measured validation rows"),
        }
    )
    tracker = table[table["Sensor"] == "Laser Tracker"].set_index("Component")
    assert np.isclose(tracker.loc[acceptance.DECLARED, "u per axis (mm)"], 0.01, rtol=0.05)
    assert np.isclose(
        tracker.loc["U (95 %) of a measurement against the prediction", "value (mm)"], result["U95_distance_mm"]
    )
    assert "instrument MPE (stated)" not in tracker.index  # none stated: no row
    other = table[table["Sensor"] == "Motion Capture"]
    assert other["Component"].tolist() == ["no budget"] and "not tested" in other["note"].iloc[0]
