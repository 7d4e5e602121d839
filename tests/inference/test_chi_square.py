"""Weighted sums of chi-square variables: known cumulants, and Pearson's approximation against chi-square
itself and against draws."""

import numpy as np
import pytest
from scipy import stats

from remaster.inference import chi_square


def test_cumulants_of_chi_square_and_of_a_weighted_sum():
    """chi-square with k dof: (k, 2k, 8k); sum w_i chi2_1: (sum w, 2 sum w^2, 8 sum w^3), which unit
    weights make chi-square's own, and scipy's moments of chi-square agree."""
    assert chi_square.cumulants(5) == (5.0, 10.0, 40.0)
    assert chi_square.cumulants(0) == (0.0, 0.0, 0.0)
    assert chi_square.weighted_cumulants([1.0, 2.0, 3.0]) == (6.0, 28.0, 288.0)
    assert chi_square.weighted_cumulants(np.ones(75)) == chi_square.cumulants(75)
    mean, variance, skew = stats.chi2.stats(7, moments="mvs")
    assert chi_square.cumulants(7) == pytest.approx((mean, variance, skew * variance**1.5), rel=1e-12)


def test_pearson_is_exact_for_chi_square_and_a_scaled_one():
    """Unit weights give chi-square itself (no shift, scale 1, k dof); one weight l, l chi2_1."""
    assert chi_square.pearson(chi_square.cumulants(75)) == pytest.approx((0.0, 1.0, 75.0), abs=1e-12)
    assert chi_square.pearson(chi_square.weighted_cumulants([4.0])) == pytest.approx((0.0, 4.0, 1.0), abs=1e-12)
    assert chi_square.pearson_sf(80.0, chi_square.cumulants(75)) == pytest.approx(stats.chi2.sf(80.0, 75))
    assert chi_square.pearson_isf(0.01, chi_square.cumulants(75)) == pytest.approx(stats.chi2.isf(0.01, 75))


def test_pearsons_approximation_against_draws_of_the_weighted_sum():
    """`pearson_sf` is within 15 % of the tail probability of 400,000 draws of a weighted sum with a
    few large weights at 10 %, 1 % and 0.1 %, and `pearson_isf` is its inverse."""
    weights = np.r_[np.ones(60), 48.0, 20.0, 9.0, 5.0, 3.0, 2.0]
    cumulants = chi_square.weighted_cumulants(weights)
    draws = (np.random.default_rng(1).standard_normal((400_000, len(weights))) ** 2) @ weights
    for tail in (0.1, 0.01, 0.001):
        assert chi_square.pearson_sf(np.quantile(draws, 1.0 - tail), cumulants) == pytest.approx(tail, rel=0.15)
        assert chi_square.pearson_sf(chi_square.pearson_isf(tail, cumulants), cumulants) == pytest.approx(tail)
