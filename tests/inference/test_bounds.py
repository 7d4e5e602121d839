"""The 95 % bound (`remaster.inference.bounds`): from a covariance, exact where it can be and close
to the sampled quantile between; from draws, the same question with the same answer; the bound on
one arm's percentile above the pooled percentile when the draws differ as wholes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from remaster.inference.bounds import (
    QUANTILE,
    bound_at_points,
    bound_from_covariances,
    bound_on_percentile_over_configurations,
)


def test_the_bound_is_exact_for_isotropic_and_rank_one_covariances():
    s = 2.0e-5
    isotropic = bound_from_covariances(np.array([s**2 * np.eye(3)]))[0]
    assert isotropic == pytest.approx(s * math.sqrt(chi2.ppf(0.95, 3)), rel=1e-9)  # chi with 3 dof
    e = np.array([0.6, 0.0, 0.8])
    rank_one = bound_from_covariances(np.array([s**2 * np.outer(e, e)]))[0]
    assert rank_one == pytest.approx(s * 1.959964, rel=1e-6)  # |N(0, s^2)|: the 97.5 % normal quantile


def test_the_bound_is_close_to_the_sampled_quantile_between():
    covariance = np.diag([4.0, 1.0, 0.25]) * 1e-8
    draws = np.random.default_rng(7).multivariate_normal(np.zeros(3), covariance, 400_000)
    sampled = np.quantile(np.linalg.norm(draws, axis=1), 0.95)
    assert bound_from_covariances(covariance[None])[0] == pytest.approx(sampled, rel=0.03)


def test_the_bound_from_draws_answers_the_covariances_question():
    rng = np.random.default_rng(3)
    covariances = np.array([np.diag([4.0, 1.0, 0.25]), np.eye(3), np.diag([1.0, 0.0, 0.0])]) * 1e-8
    draws = np.stack([rng.multivariate_normal(np.zeros(3), c, 200_000) for c in covariances], axis=1)  # (K, n, 3)
    from_draws = bound_at_points(np.linalg.norm(draws, axis=-1))
    assert from_draws.shape == (3,)
    np.testing.assert_allclose(from_draws, bound_from_covariances(covariances), rtol=0.03)
    assert np.all(np.isnan(bound_at_points(np.zeros((0, 4))))) and bound_at_points(np.zeros((0, 4))).shape == (4,)


def test_the_bound_on_an_arms_percentile_exceeds_the_pooled_percentile():
    # each draw (arm) errs by its own scale at every configuration: a draw in the tail errs everywhere
    rng = np.random.default_rng(5)
    scale = rng.lognormal(0.0, 0.5, 400)
    distances = scale[:, None] * np.abs(rng.standard_normal((400, 300)))
    bound = bound_on_percentile_over_configurations(distances)
    per_arm = np.quantile(distances, QUANTILE, axis=1)
    assert np.mean(per_arm <= bound) == pytest.approx(QUANTILE, abs=0.01)
    assert bound > np.quantile(distances, QUANTILE)
    assert math.isnan(bound_on_percentile_over_configurations(np.zeros((0, 0))))
