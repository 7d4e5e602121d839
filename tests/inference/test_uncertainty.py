"""Expanded uncertainties with known answers: t coverage factors, Welch-Satterthwaite, the CR2
uncertainty of a clustered mean (closed forms and its coverage with few clusters), the
delete-a-group jackknife (the classical variance of a mean) and the between-design component."""

import math

import numpy as np
import pytest

from remaster.inference import uncertainty


def test_coverage_factors_are_the_t_and_normal_quantiles():
    assert uncertainty.coverage_factor(math.inf) == pytest.approx(1.959964, abs=1e-6)
    assert uncertainty.coverage_factor(9) == pytest.approx(2.262157, abs=1e-6)  # t_0.975(9), tables
    assert uncertainty.coverage_factor(29) == pytest.approx(2.045230, abs=1e-6)
    assert math.isnan(uncertainty.coverage_factor(0)) and math.isnan(uncertainty.coverage_factor(math.nan))


def test_welch_satterthwaite_closed_forms():
    # one finite component: its own dof scaled by (u_c^2 / u_i^2)^2
    assert uncertainty.welch_satterthwaite([3.0, 4.0], [math.inf, 9]) == pytest.approx(9 * 25**2 / 16**2)
    # two equal components of equal dof: twice the dof
    assert uncertainty.welch_satterthwaite([1.0, 1.0], [5, 5]) == pytest.approx(10.0)
    assert uncertainty.welch_satterthwaite([1.0], [math.inf]) == math.inf


def test_cr2_on_equal_clusters_is_the_spread_of_the_cluster_means():
    """Equal clusters: (1/N^2) sum_g (n r_g)^2 / (1 - 1/G) = s^2(cluster means) / G."""
    rng = np.random.default_rng(1)
    clusters = np.repeat(np.arange(7), 4)
    values = rng.normal(size=len(clusters))
    mean, u, count = uncertainty.cr2_mean(values, clusters)
    means = values.reshape(7, 4).mean(axis=1)
    assert mean == pytest.approx(values.mean()) and count == 7
    assert u == pytest.approx(means.std(ddof=1) / math.sqrt(7), rel=1e-12)


def test_cr2_on_unequal_clusters_by_hand():
    # clusters {1, 2} and {6}: mean 3, sums -3 and 3, sizes 2 and 1, N = 3
    mean, u, count = uncertainty.cr2_mean([1.0, 2.0, 6.0], ["a", "a", "b"])
    assert mean == 3.0 and count == 2
    assert u == pytest.approx(math.sqrt((9 / (1 - 2 / 3) + 9 / (1 - 1 / 3)) / 9))
    assert math.isnan(uncertainty.cr2_mean([1.0, 2.0], [0, 0])[1])  # one cluster: no u


def _coverage(sizes, seed: int, runs: int = 4000) -> tuple[float, float]:
    """(CR2 with t(G-1), former std of cluster means / sqrt(G) with k = 2) coverage of the true mean
    of clusters of `sizes` sharing a cluster effect (std 1) with noise (std 0.3)."""
    rng = np.random.default_rng(seed)
    sizes = np.asarray(sizes)
    clusters = np.repeat(np.arange(len(sizes)), sizes)
    k = uncertainty.coverage_factor(len(sizes) - 1)
    covered, former = [], []
    for _ in range(runs):
        values = 1.0 + rng.normal(0, 1.0, len(sizes))[clusters] + rng.normal(0, 0.3, len(clusters))
        mean, u, _ = uncertainty.cr2_mean(values, clusters)
        covered.append(abs(mean - 1.0) <= k * u)
        means = np.array([values[clusters == g].mean() for g in range(len(sizes))])
        former.append(abs(mean - 1.0) <= 2 * means.std(ddof=1) / math.sqrt(len(sizes)))
    return float(np.mean(covered)), float(np.mean(former))


def test_cr2_with_t_of_g_minus_1_covers_95_percent_with_few_clusters():
    """Six equal clusters: the CR2 pivot is exactly t(5), so the coverage is 95 % (binomial sd of
    4000 runs 0.35 %); the former k = 2 covers P(|t5| < 2) = 89.8 %. Six unequal clusters: CR2
    with t(G-1) stays near 95 % (Bell-McCaffrey: slightly below with unequal sizes)."""
    covered, former = _coverage([4] * 6, seed=7)
    assert 0.94 <= covered <= 0.96 and 0.88 <= former <= 0.915
    covered, former = _coverage([2, 3, 4, 4, 5, 6], seed=8)
    assert 0.925 <= covered <= 0.96 and former < 0.9


def test_the_jackknife_of_a_mean_is_the_classical_variance():
    rng = np.random.default_rng(3)
    values = rng.normal(size=24)
    # groups of one value: s^2 / n
    leave_one_out = np.array([np.delete(values, i).mean() for i in range(24)])
    assert uncertainty.jackknife_variance(leave_one_out) == pytest.approx(values.var(ddof=1) / 24, rel=1e-12)
    # eight equal groups of three: s^2(group means) / 8
    groups = np.repeat(np.arange(8), 3)
    leave_group_out = np.array([values[groups != g].mean() for g in range(8)])
    means = values.reshape(8, 3).mean(axis=1)
    assert uncertainty.jackknife_variance(leave_group_out) == pytest.approx(means.var(ddof=1) / 8, rel=1e-12)


def test_the_between_design_component_is_what_the_jackknife_holds_beyond_the_posterior():
    u_b, dof = uncertainty.between_design([3.0, 5.0], [5.0, 4.0], 10)
    assert u_b == pytest.approx([4.0, 0.0])  # sqrt(25 - 9); the posterior already covers 4
    assert dof[0] == pytest.approx(9.0)  # the jackknife sets u_c: its K - 1
    assert dof[1] == pytest.approx(9 * 25**2 / 16**2)  # u_c = 5 from the posterior, u_J = 4
    u_c, nu = uncertainty.with_between(3.0, 4.0, 5.0, 10)
    assert u_c == pytest.approx(5.0) and nu == pytest.approx(9.0)
