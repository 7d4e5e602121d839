"""The truth's rank among a posterior's draws (`remaster.api.truth`'s simulation-based calibration),
held to known answers: a truth drawn as the draws are ranks uniformly over repetitions; a truth far
in the draws' tail ranks near 0 or 1; and the arm-level rank of the mean PIT does the same where
one arm's errors are correlated across its commands."""

import numpy as np
from scipy import stats

from remaster.api.truth import mean_pit_rank, normalized_rank


def test_a_rank_counts_the_draws_below_and_ties_half():
    draws = np.array([1.0, 2.0, 3.0, 3.0])
    assert normalized_rank(0.5, draws) == 0.0
    assert normalized_rank(3.0, draws) == 0.75  # two below, two tied (each half)
    assert normalized_rank(9.0, draws) == 1.0
    assert np.allclose(normalized_rank([0.5, 2.5], np.column_stack([draws, draws])), [0.0, 0.5])


def test_a_truth_drawn_as_the_draws_are_ranks_uniformly_and_one_in_the_tail_at_its_end():
    rng = np.random.default_rng(7)
    ranks = [normalized_rank(rng.normal(), rng.normal(size=200)) for _ in range(400)]
    assert stats.kstest(ranks, "uniform").pvalue > 0.01
    assert normalized_rank(5.0, rng.normal(size=200)) > 0.99
    assert normalized_rank(-5.0, rng.normal(size=200)) < 0.01


def _arm_errors(rng, count: int, commands: int = 30, scale: float = 1.0) -> np.ndarray:
    """(count, commands): each arm's error at every command, one common part per arm (correlated
    across its commands, as one arm's are) and a part per command."""
    common = rng.normal(size=(count, 1))
    return scale * np.abs(common + 0.3 * rng.normal(size=(count, commands)))


def test_the_mean_pit_of_an_arm_drawn_as_the_draws_ranks_uniformly():
    """Its mean PIT alone is not uniform (the mean of correlated PITs); its rank among the draws' own is."""
    rng = np.random.default_rng(11)
    ranks = [mean_pit_rank(_arm_errors(rng, 1)[0], _arm_errors(rng, 150))[1] for _ in range(300)]
    assert stats.kstest(ranks, "uniform").pvalue > 0.01
    assert 0.0 <= min(ranks) and max(ranks) <= 1.0


def test_an_arm_farther_than_the_draws_ranks_near_one_and_nearer_near_zero():
    rng = np.random.default_rng(13)
    draws = _arm_errors(rng, 200)
    truth, rank = mean_pit_rank(np.full(30, 10.0), draws)
    assert truth == 1.0 and rank == 1.0
    truth, rank = mean_pit_rank(np.zeros(30), draws)
    assert truth == 0.0 and rank == 0.0
