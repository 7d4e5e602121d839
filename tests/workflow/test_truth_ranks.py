"""The truth's rank among a posterior's draws (`remaster.api.truth`'s simulation-based calibration),
held to known answers: a truth drawn as the draws are ranks uniformly over repetitions; a truth far
in the draws' tail ranks near 0 or 1; and the arm-level rank of the mean PIT does the same where
one arm's errors are correlated across its commands; and the zero-offsets a fit can recover of a
truth whose links are turned."""

import numpy as np
from scipy import stats

from remaster.api.truth import mean_pit_rank, normalized_rank, recoverable_zero_offsets
from remaster.campaigns.arm_kinds import chain_of, iiwa_scenario
from remaster.campaigns.simulation import TrueRobot

from ..conftest import REPO


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


def test_the_recoverable_zero_offset_takes_a_links_turn_about_its_joints_axis():
    """A truth's zero-offsets as a fit can recover them: its own, and joint 1 turned by a yaw of the
    fixed transform before it (the iiwa's joint 1 turns about z), nothing added where nothing turns."""
    spec = iiwa_scenario("turns")
    chain = chain_of(spec, REPO)
    offsets = np.radians(spec["truth"]["zero_offsets_deg"])
    assert np.array_equal(recoverable_zero_offsets(chain, TrueRobot(offsets)), offsets)
    motions = np.zeros((chain.n_joints + 1, 6))
    motions[0, 5] = 1.0e-4
    turned = recoverable_zero_offsets(chain, TrueRobot(offsets, link_motions=motions))
    assert np.allclose(turned - offsets, np.eye(chain.n_joints)[0] * 1.0e-4, atol=1e-9)
