"""The refit's parameter table: what the data determine of a parameter its prior decides."""

import numpy as np
import pytest

from remaster.loop import refit
from remaster.units import DEG, MM


def test_the_determined_combination_is_the_parameter_less_its_regression_on_the_others():
    """q2 and a link rotation each 1 deg wide but their difference known to 0.01 deg (correlation
    1 - 5e-5): the combination is q2 - 1 * rotation with the conditional std sqrt(1 - rho^2) deg;
    an uncorrelated length is left out of it."""
    rho = 1 - 5e-5
    names = ["zero_offsets.q2", "link_geometry.L2.ry", "link_geometry.L3.x"]
    covariance = np.diag([DEG, DEG, MM]) @ np.array([[1, rho, 0], [rho, 1, 0], [0, 0, 1.0]]) @ np.diag([DEG, DEG, MM])
    scale = {"zero_offsets.q2": DEG, "link_geometry.L2.ry": DEG, "link_geometry.L3.x": MM}
    text = refit.determined_combination("zero_offsets.q2", names, covariance, scale)
    assert text.startswith("+1*zero_offsets.q2 -1*link_geometry.L2.ry ")
    assert "L3.x" not in text
    std = float(text.split("(std ")[1].rstrip(")"))
    assert std == pytest.approx(np.sqrt(1 - rho**2), rel=1e-3)


def test_a_parameter_correlated_with_nothing_has_no_combination():
    names = ["zero_offsets.q2", "link_geometry.L3.x"]
    scale = {"zero_offsets.q2": DEG, "link_geometry.L3.x": MM}
    covariance = np.diag([DEG**2, MM**2])
    assert refit.determined_combination("zero_offsets.q2", names, covariance, scale) == ""
    assert refit.determined_combination("zero_offsets.q2", names[:1], covariance[:1, :1], scale) == ""


def test_the_priors_share_of_a_posterior_variance_against_known_answers():
    """One parameter, var = 1 / (h + q): the priors' share is q / (h + q). Two parameters the data
    see only as a sum, one of wide prior and one of tight: the wide one's variance is the tight
    one's prior (share 1) although its std is 1 % of its own prior; seen apart, neither is set by
    the priors."""
    assert refit.prior_shares([[1.0 / (3.0 + 1.0)]], [1.0]) == pytest.approx([0.25])
    prior_std = np.array([0.1, 1e-3])
    traded = np.linalg.inv(np.full((2, 2), 1e10) + np.diag(1.0 / prior_std**2))
    assert refit.prior_shares(traded, prior_std) == pytest.approx([1.0, 1.0], abs=1e-3)
    assert np.sqrt(traded[0, 0]) / prior_std[0] == pytest.approx(0.01, rel=1e-3)
    apart = np.linalg.inv(np.diag([1e10, 1e10]) + np.diag(1.0 / prior_std**2))
    assert refit.prior_shares(apart, prior_std) == pytest.approx([1e-8, 1e-4], rel=1e-3)
    assert refit.prior_shares(apart, [np.inf, np.inf]) == pytest.approx([0.0, 0.0])
