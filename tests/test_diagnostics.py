"""The convergence diagnostics (rank-normalised split R-hat, bulk and tail ESS, MCSE of the mean)
on chains with known answers, what they say of failed runs, and the agreement arithmetic of the
samplers' cross-check with the configuration's floor. Every test has a fixed seed."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import signal

from remaster import diagnostics

from .conftest import validated_config

CROSS_CHECK = validated_config()["fit"]["cross_check"]  # the schema's defaults: tolerance, floor, ...


def statistic(chains, name: str) -> np.ndarray:
    """(P,) one of `diagnostics.convergence`'s statistics."""
    return diagnostics.convergence(chains, [name])[name]


def ar1(rng, phi, n, shape=()):
    """AR(1) with unit marginal variance along axis 0: ESS = n (1 - phi) / (1 + phi) for large n."""
    noise = rng.standard_normal((n, *shape)) * math.sqrt(1 - phi**2)
    noise[0] = rng.standard_normal(shape)  # start in the stationary distribution
    return signal.lfilter([1.0], [1.0, -phi], noise, axis=0)


def test_independent_normal_draws_in_four_chains():
    """iid N(0, 2^2) in 4 chains of 2000: R-hat 1, both ESS the number of draws, MCSE sd / sqrt(n)."""
    rng = np.random.default_rng(0)
    chains = [2.0 * rng.standard_normal((2_000, 3)) for _ in range(4)]
    report = diagnostics.chain_report(chains)
    assert np.all(np.abs(report["rhat"] - 1) < 0.01), report["rhat"]
    # the ESS of n iid draws scatters by a few % about n
    np.testing.assert_allclose(report["ess_bulk"], 8_000, rtol=0.1)
    np.testing.assert_allclose(report["ess_tail"], 8_000, rtol=0.15)
    np.testing.assert_allclose(report["mcse_mean"], 2.0 / math.sqrt(8_000), rtol=0.1)
    assert np.all(np.abs(report["mean"]) < 4 * report["mcse_mean"])


@pytest.mark.parametrize("phi", [0.5, 0.8])
def test_ess_of_ar1_chains(phi):
    """4 AR(1) chains: bulk ESS and the mean's n (1 - phi) / (1 + phi), within 10 % (a few sd of
    the estimator at these lengths); MCSE of the mean sd sqrt((1 + phi) / (1 - phi) / n)."""
    rng = np.random.default_rng(1)
    chains = [ar1(rng, phi, 20_000, (2,)) for _ in range(4)]
    expected = 80_000 * (1 - phi) / (1 + phi)
    np.testing.assert_allclose(statistic(chains, "ess_bulk"), expected, rtol=0.1)
    np.testing.assert_allclose(statistic(chains, "mcse_mean"), 1 / math.sqrt(expected), rtol=0.1)
    assert np.all(np.abs(statistic(chains, "rhat") - 1) < 0.01)


def test_an_ensembles_walkers_are_chains():
    """(n, W, P): every walker one chain, so ESS counts every walker's draws; one ensemble
    and the same walkers given as two ensembles (or as one-walker chains) are the same chains."""
    rng = np.random.default_rng(2)
    ensemble = ar1(rng, 0.8, 5_000, (8, 2))
    np.testing.assert_allclose(statistic([ensemble], "ess_bulk"), 40_000 / 9, rtol=0.1)
    as_halves = [ensemble[:, :4], ensemble[:, 4:]]
    as_chains = [ensemble[:, k] for k in range(8)]
    one = diagnostics.convergence([ensemble])
    for same in (diagnostics.convergence(as_halves), diagnostics.convergence(as_chains)):
        for name in diagnostics.STATISTICS:
            np.testing.assert_array_equal(one[name], same[name])
    # one walker stuck away from the others: R-hat over walkers sees it
    ensemble[:, 3] += 3.0
    assert np.all(statistic([ensemble], "rhat") > 1.1)


def test_rhat_sees_chains_apart_and_a_drifting_chain():
    rng = np.random.default_rng(3)
    good = [rng.standard_normal((2_000, 3)) for _ in range(4)]
    assert np.all(np.abs(statistic(good, "rhat") - 1) < 0.01)
    apart = [good[0], good[1], good[2] + 1.0, good[3] + 1.0]  # two pairs of chains one sd apart
    assert np.all(statistic(apart, "rhat") > 1.1)
    # one chain of two still drifting by 4 sd: the split halves catch it
    drifting = [good[0], good[1] + np.linspace(0, 4, 2_000)[:, None]]
    assert np.all(statistic(drifting, "rhat") > 1.1)
    # the tails: same centre, one chain four times as wide, caught by the folded R-hat
    wide = [good[0], good[1], good[2], 4 * good[3]]
    assert np.all(statistic(wide, "rhat") > 1.1)


def test_what_failed_runs_leave_is_nan_not_an_error():
    """Short, stuck, NaN, empty and single chains: NaN where a statistic is undefined, never a
    warning or an exception. A parameter that never moves has no ESS: arviz would count all its
    draws."""
    rng = np.random.default_rng(4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        good = [rng.standard_normal((500, 2)) for _ in range(2)]
        stuck = [np.column_stack([np.full(500, 0.25), g[:, 1]]) for g in good]
        report = diagnostics.chain_report(stuck, ["stuck", "moving"])
        assert report.loc["stuck", ["rhat", "ess_bulk", "ess_tail", "mcse_mean"]].isna().all()
        assert report.loc["moving", ["rhat", "ess_bulk", "ess_tail", "mcse_mean"]].notna().all()
        holed = [good[0].copy(), good[1]]
        holed[0][7, 1] = np.nan
        report = diagnostics.chain_report(holed, ["x", "y"])
        assert report.loc["x"].notna().all()
        assert report.loc["y", ["mean", "rhat", "ess_bulk", "ess_tail", "mcse_mean"]].isna().all()
        short = diagnostics.chain_report([np.ones((3, 2)) + rng.standard_normal((3, 2)) for _ in range(2)])
        assert short[["rhat", "ess_bulk", "ess_tail", "mcse_mean"]].isna().all().all()
        empty = diagnostics.chain_report([np.zeros((0, 2)), np.zeros((0, 2))], ["x", "y"])
        assert empty.isna().all().all()
        single = diagnostics.chain_report([good[0]])  # R-hat needs two chains; ESS does not
        assert single["rhat"].isna().all() and single["ess_bulk"].notna().all()


def test_chain_report_columns():
    rng = np.random.default_rng(5)
    chains = [ar1(rng, 0.5, 1_000, (3,)) for _ in range(2)]
    report = diagnostics.chain_report(chains, ["a", "b", "c"])
    assert list(report.index) == ["a", "b", "c"] and report.index.name == "parameter"
    assert list(report.columns) == ["mean", "std", "q2.5", "q97.5", "rhat", "ess_bulk", "ess_tail", "mcse_mean"]
    assert np.all(report["q2.5"] < report["mean"]) and np.all(report["mean"] < report["q97.5"])
    mean, std, mcse = diagnostics.moments(chains)
    np.testing.assert_array_equal(mcse, report["mcse_mean"])
    np.testing.assert_array_equal(mean, report["mean"])


# ----------------------------------------------------------------------------- agreement (the cross-check's arithmetic)


def test_agreement_marks_a_shifted_method():
    names = ["x", "y"]
    mean, std = np.array([1.0, 2.0]), np.array([0.1, 0.2])
    results = {
        "reference": (mean, std, np.array([0.005, 0.01])),
        "good": (mean + np.array([0.001, -0.002]), std, np.array([0.005, 0.01])),
        "shifted": (mean + np.array([0.0, 0.2]), std, np.array([0.005, 0.01])),
    }
    table = diagnostics.agreement(results, names, CROSS_CHECK["floor"])
    # 0.2 over the floor (0.1 of the std 0.2 = 0.02: larger than the Monte Carlo error 0.014)
    z = 0.2 / (CROSS_CHECK["floor"] * 0.2)
    assert table.loc["y", ("z", "shifted")] == pytest.approx(z) and table.loc["x", ("z", "reference")] == 0
    assert set(table.columns.get_level_values("quantity")) == {"mean", "std", "z"}
    assert table.attrs == {"reference": "reference", "floor": CROSS_CHECK["floor"]}
    assert diagnostics.disagreements(table, CROSS_CHECK["tolerance"]) == [
        ("y", "shifted", "reference", pytest.approx(z))
    ]
    table.attrs.clear()  # attrs can be lost on the way: the reference is then the all-zero z column
    assert diagnostics.disagreements(table, CROSS_CHECK["tolerance"]) == [
        ("y", "shifted", "reference", pytest.approx(z))
    ]
    del results["shifted"]
    assert diagnostics.disagreements(diagnostics.agreement(results, names, CROSS_CHECK["floor"]), 4.0) == []
    assert len(diagnostics.disagreements(diagnostics.agreement(results, names, 0.0), 0.1)) == 2


def test_agreement_floor_when_there_is_no_monte_carlo_error():
    """mcse 0 on both sides (e.g. Laplace vs Laplace): the error is the floor times the larger std;
    a NaN mean is a disagreement."""
    names, std, zero = ["x"], np.array([1.0]), np.zeros(1)
    floor, tolerance = CROSS_CHECK["floor"], CROSS_CHECK["tolerance"]
    close = {"laplace": (np.zeros(1), std, zero), "other": (np.array([0.75 * tolerance * floor]), std, zero)}
    assert diagnostics.agreement(close, names, floor).loc["x", ("z", "other")] == pytest.approx(0.75 * tolerance)
    assert diagnostics.disagreements(diagnostics.agreement(close, names, floor), tolerance) == []
    far = {"laplace": (np.zeros(1), std, zero), "other": (np.array([1.5 * tolerance * floor]), std, zero)}
    assert [o[:2] for o in diagnostics.disagreements(diagnostics.agreement(far, names, floor), tolerance)] == [
        ("x", "other")
    ]
    nan = {"laplace": (np.zeros(1), std, zero), "other": (np.array([np.nan]), std, zero)}
    assert len(diagnostics.disagreements(diagnostics.agreement(nan, names, floor), tolerance)) == 1
