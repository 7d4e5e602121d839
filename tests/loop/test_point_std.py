"""Per-point instrument std columns of a sensor table (`std`, or `std_x, std_y, std_z`): refused
with the file, column and rows when malformed, and used by the loop's models as per-row weights
whose likelihood is the sum of the independent normal densities N(0, (sigma w_ia)^2) (a closed
form computed here with scipy, not by the code under test)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from remaster.campaigns import scenario
from remaster.campaigns.arm_kinds import chain_of, iiwa_scenario
from remaster.campaigns.campaign import sensor_data
from remaster.errors import InputError
from remaster.inference import blocks, fit
from remaster.inference.readings import readings

from ..conftest import REPO

# these run the loop closure on simulated campaigns (`-m 'not slow'` leaves them out)
pytestmark = pytest.mark.slow

LOG_2PI = math.log(2.0 * math.pi)


@pytest.fixture(scope="module")
def simulated():
    spec = iiwa_scenario("point-std", seed=21)
    chain = chain_of(spec, REPO)
    out = scenario.simulate(spec, chain)
    return chain, out.metadata["sensors"]["laser_tracker"], out.tables["laser_tracker"]


def _sensor(simulated, table):
    chain, meta, _ = simulated
    return sensor_data(
        "laser_tracker", {**meta, "marker": np.array(meta["marker"])}, table, chain.n_joints, "lt.parquet"
    )


@pytest.mark.parametrize(
    "change, key, message",
    [
        ({"std": 1e-5, "std_x": 1e-5}, "std, std_x", "not both"),
        ({"std_x": 1e-5, "std_y": 1e-5}, "std_z", "missing"),
        ({"std": -1e-5}, "std", "positive finite"),
        ({"std": 2e-2}, "std", "millimetres stored as metres"),
    ],
)
def test_malformed_std_columns_are_named_with_file_column_and_rows(simulated, change, key, message):
    table = simulated[2].copy()
    for column, value in change.items():
        table[column] = value
    with pytest.raises(InputError, match=message) as error:
        _sensor(simulated, table)
    text = str(error.value)
    assert "lt.parquet" in text and key in text
    if "positive" in message or "millimetres" in message:
        assert "row" in text


def test_a_missing_std_on_a_seen_row_is_refused_and_one_on_an_unseen_row_is_not(simulated):
    table = simulated[2].copy()
    table["std"] = 1e-5
    table.loc[3, "std"] = np.nan
    with pytest.raises(InputError, match="positive finite") as error:
        _sensor(simulated, table)
    assert "3" in str(error.value)
    table.loc[3, ["x", "y", "z"]] = np.nan  # marker not seen: its std is not needed
    assert _sensor(simulated, table).point_std([3]).shape == (1, 3)


def test_the_weighted_likelihood_is_the_sum_of_normal_densities(simulated, rng):
    chain, _, table = simulated
    table = table.copy()
    stds = rng.uniform(0.5e-5, 3e-5, (len(table), 3))
    table[["std_x", "std_y", "std_z"]] = stds
    sensor = _sensor(simulated, table)
    data = readings(chain, sensor, "optimization")
    measured_rows = sensor.measured_rows()
    reference = math.sqrt(np.mean(stds[measured_rows] ** 2))
    np.testing.assert_allclose(data.weights, stds[data.rows] / reference, rtol=1e-12)
    t_nr = fit.register(chain, sensor).t_nr
    model = blocks.BlockModel(chain, data, sensor.marker, t_nr, ["sensor_scale"])
    theta = 1e-4 * rng.standard_normal(len(model.names))
    sigma = 2.3e-5
    residuals = model.residuals(theta)
    k = residuals.size
    loglik = -0.5 * k * LOG_2PI - k * math.log(sigma) - model.sum_squares(theta) / (2 * sigma**2) + model.noise_log_det
    expected = stats.norm.logpdf(residuals, scale=sigma * stds[data.rows] / reference).sum()
    assert loglik == pytest.approx(expected, rel=1e-10)
    # without the columns: the paper's isotropic likelihood
    plain = readings(chain, _sensor(simulated, simulated[2]), "optimization")
    assert plain.weights is None


def test_the_closure_is_tested_against_the_instruments_own_std(simulated):
    """A tracker whose per-point std columns say 30 um where campaign.yaml states 10 um: the table's
    noise (the simulator's, 30 um) is at the columns' level, so the loop is closed against them and
    would not be against the stated noise alone."""
    from remaster.loop import loop_closure, noise_floor

    from ..conftest import loop_settings

    chain, meta, _ = simulated
    spec = iiwa_scenario("point-std-floor", seed=22)
    spec["sensors"]["laser_tracker"]["noise"] = 3e-5
    out = scenario.simulate(spec, chain)
    table = out.tables["laser_tracker"].copy()
    table["std"] = 3e-5
    reports = {}
    for name, frame in (("columns", table), ("stated", out.tables["laser_tracker"])):
        sensor = sensor_data(
            "laser_tracker", {**meta, "noise": 1e-5, "marker": np.array(meta["marker"])}, frame, 7, "lt.parquet"
        )
        registration = fit.register(chain, sensor)
        _, analysis, _ = fit.build_model(chain, sensor, registration.t_nr)
        reports[name] = loop_closure.close_loop(
            chain, sensor, registration.t_nr, analysis.held, np.random.default_rng(0), loop_settings(mcmc=None)
        ).report.closure
    assert reports["columns"]["measured_point_std_mm"] == pytest.approx(0.03)
    assert reports["columns"]["noise_floor_mm"] == pytest.approx(0.03)
    assert reports["columns"]["closed"] is True
    assert reports["stated"]["measured_point_std_mm"] is None
    assert reports["stated"]["noise_floor_mm"] == pytest.approx(0.01)
    assert reports["stated"]["closed"] is False
    assert noise_floor.noise_floor(1e-5, None, 3e-5) == 3e-5


def test_a_range_transverse_noise_implies_its_rms_per_axis():
    from remaster.loop import noise_floor

    points = np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    # k^2 = 1 + (g d)^2 = 5 and 2: per axis (1 + 2 k^2) / 3 = 11/3 and 5/3
    expected = 1e-5 * math.sqrt((11.0 / 3.0 + 5.0 / 3.0) / 2.0)
    assert noise_floor.range_transverse_rms(1e-5, 1.0, points) == pytest.approx(expected, rel=1e-12)
    assert noise_floor.range_transverse_rms(1e-5, 0.0, points) == pytest.approx(1e-5, rel=1e-12)


def test_the_certificate_warns_of_a_noise_shape_not_kept_and_of_one_kept_above_the_floor():
    from remaster.loop import closure_test

    points = np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    refused = {"chosen": "isotropic", "refused": "it takes up error the model lacks"}
    rms, warnings = closure_test._noise_model(refused, 1e-5, points)
    assert rms is None and warnings == [
        "the laser tracker's range/transverse noise model was not kept: it takes up error the model lacks"
    ]
    kept = {"chosen": "range_transverse", "sigma_range_mm": 0.01, "transverse_growth_per_m": 1.0}
    rms, warnings = closure_test._noise_model(kept, 1e-5, points)  # 1.63 x the floor per axis
    assert rms == pytest.approx(1e-5 * math.sqrt(8.0 / 3.0)) and "1.6 x the instrument's noise floor" in warnings[0]
    assert closure_test._noise_model(kept, 2e-5, points) == (rms, [])
    assert closure_test._noise_model({"chosen": "isotropic"}, 1e-5, points) == (None, [])
