"""The refit's independence sampling against known answers: a proposal that follows a curved valley
(`RidgeProposal`) on a twisted Gaussian whose moments are known in closed form, and sigma
integrated out (`posterior_targets.SigmaMarginalTarget`) against quadrature of the joint posterior."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from remaster import diagnostics
from remaster.inference.blocks import paper_model
from remaster.inference.posterior_targets import PosteriorTarget, SigmaMarginalTarget
from remaster.inference.sampling.chains import run_chains
from remaster.inference.sampling.independence import RidgeProposal, metropolis_independence
from remaster.inference.sampling.target import CallableTarget, Chain

from .test_model import simulated

# A twisted Gaussian (Haario, Saksman & Tamminen 1999): x ~ N(0, diag(S^2, 1, 1, 1)) and
# y = (x1, x2 + B (x1^2 - S^2), x3, x4). The twist has Jacobian 1, so the density of y is known,
# and so are its moments: E y = 0, var y2 = 1 + 2 B^2 S^4. Its mode is at y2 = -B S^2, with the
# Hessian of the untwisted Gaussian there: a Laplace approximation misses both the mean and the
# spread of y2.
S, B = 3.0, 0.1
NAMES = ("y1", "y2", "y3", "y4")


def twisted(y):
    y = np.atleast_2d(y)
    x2 = y[:, 1] - B * (y[:, 0] ** 2 - S**2)
    return -0.5 * ((y[:, 0] / S) ** 2 + x2**2 + y[:, 2] ** 2 + y[:, 3] ** 2)


TARGET = CallableTarget(NAMES, np.ones(4), twisted)
MODE = np.array([0.0, -B * S**2, 0.0, 0.0])
LAPLACE = np.diag([S**2, 1.0, 1.0, 1.0])
EXACT_VARIANCE = np.array([S**2, 1 + 2 * B**2 * S**4, 1.0, 1.0])


def run(proposal, seed=3, n_samples=6000):
    return run_chains(
        metropolis_independence,
        TARGET,
        np.random.default_rng(seed),
        2,
        MODE,
        mean=MODE,
        covariance=LAPLACE,
        n_samples=n_samples,
        burn_in=500,
        dof=16.0,
        inflation=1.1,
        proposal=proposal,
    )


def test_the_bent_direction_is_found_and_the_straight_ones_left_gaussian():
    proposal = RidgeProposal.fit(TARGET, MODE, LAPLACE, dof=16.0, inflation=1.1)
    assert proposal is not None
    bent = proposal.report(NAMES)
    assert len(bent) == 1 and bent[0][0][0] == "y1" and abs(bent[0][0][1]) == pytest.approx(1.0)
    # the valley's floor is the twist: y2 = B (y1^2 - S^2), y1 the bent coordinate in y's units
    k = proposal.bent[0]
    y1 = proposal.basis[0, k] * proposal.knots[0]
    floor = MODE + proposal.floors[0] @ proposal.basis[:, proposal.straight].T
    np.testing.assert_allclose(floor[:, 1], B * (y1**2 - S**2), atol=1e-3 * S**2)
    np.testing.assert_allclose(floor[:, [0, 2, 3]], 0.0, atol=1e-6)
    # a Gaussian target has no bent direction: the Student-t is the proposal
    gaussian = CallableTarget(NAMES, np.ones(4), lambda y: -0.5 * np.sum(np.atleast_2d(y) ** 2, axis=1))
    assert RidgeProposal.fit(gaussian, np.zeros(4), np.eye(4), dof=16.0, inflation=1.1) is None


def test_draws_follow_the_stated_density():
    """log_density is the density the draws come from: it integrates to one, and the draws'
    mean of a function equals its integral against it (2-D, on a grid)."""
    target = CallableTarget(
        NAMES[:2], np.ones(2), lambda y: twisted(np.column_stack([y, np.zeros((len(np.atleast_2d(y)), 2))]))
    )
    proposal = RidgeProposal.fit(target, MODE[:2], LAPLACE[:2, :2], dof=16.0, inflation=1.1)
    g1, g2 = np.linspace(-40, 40, 801), np.linspace(-30, 40, 701)
    grid = np.stack(np.meshgrid(g1, g2, indexing="ij"), axis=-1).reshape(-1, 2)
    density = np.exp(proposal.log_density(grid)).reshape(len(g1), len(g2))
    total = integrate.trapezoid(integrate.trapezoid(density, g2, axis=1), g1)
    assert total == pytest.approx(1.0, abs=2e-3)
    second = integrate.trapezoid(integrate.trapezoid(density * g2[None, :] ** 2, g2, axis=1), g1)
    draws = proposal.draw(np.random.default_rng(1), 200_000)
    spread = np.std(draws[:, 1] ** 2) / np.sqrt(len(draws))
    assert np.mean(draws[:, 1] ** 2) == pytest.approx(second, abs=4 * spread)


def test_independence_sampling_along_the_valley_recovers_the_exact_moments():
    proposal = RidgeProposal.fit(TARGET, MODE, LAPLACE, dof=16.0, inflation=1.1)
    chains = run(proposal)
    report = diagnostics.chain_report(chains, list(NAMES))
    assert report["rhat"].max() < 1.02 and report["ess_bulk"].min() > 2000
    draws = np.concatenate([c.samples for c in chains])
    ess = report["ess_bulk"].to_numpy()
    np.testing.assert_array_less(np.abs(draws.mean(axis=0)), 4 * np.sqrt(EXACT_VARIANCE / ess))
    # the variance's Monte Carlo error: var(y^2) / ess, var(y^2) <= 3 var^2 for these tails (x 2 margin)
    np.testing.assert_allclose(draws.var(axis=0), EXACT_VARIANCE, rtol=4 * np.sqrt(6 / ess).max())
    # the Laplace approximation's own Student-t proposal mixes far worse on the same target
    plain = diagnostics.chain_report(run(None), list(NAMES))
    assert plain["ess_bulk"].min() < report["ess_bulk"].min() / 3


@pytest.fixture(scope="module")
def model(iiwa):
    q, measured, marker, t_nr, _ = simulated(iiwa, np.random.default_rng(4), n=12, noise=2e-4)
    return paper_model(iiwa, q, measured, marker, t_nr)


def test_sigma_integrates_out_as_quadrature_of_the_joint_posterior(model):
    """log p(theta) from the closed form against log of the joint posterior integrated over sigma
    numerically, at a few parameter vectors: equal up to one constant."""
    joint, marginal = PosteriorTarget(model), SigmaMarginalTarget(model)
    thetas = np.random.default_rng(5).normal(0.0, 1e-4, (4, len(model.names)))
    closed = marginal.log_prob_many(thetas)
    numeric = []
    for theta in thetas:
        scale = np.sqrt(model.sum_squares(theta) / (3 * model.n_points))
        peak = joint.log_prob(np.append(theta, scale))
        value, _ = integrate.quad(
            lambda s, theta=theta, peak=peak: np.exp(joint.log_prob(np.append(theta, s)) - peak), 0.2 * scale, 5 * scale
        )
        numeric.append(peak + np.log(value))
    np.testing.assert_allclose(closed - closed[0], np.array(numeric) - numeric[0], atol=1e-6)


def test_sigma_is_drawn_from_its_conditional_posterior(model):
    """Given theta, sigma's draws follow p(sigma | theta) ~ sigma^-(N + 2) exp(-SS / 2 sigma^2),
    its CDF by quadrature; the joint log-posterior is stored with them."""
    theta = np.zeros(len(model.names))
    chain = Chain(np.repeat(theta[None], 4000, axis=0), np.zeros(4000), 0.5, model.names, "test")
    completed = SigmaMarginalTarget(model).with_sigma(chain, np.random.default_rng(6))
    assert completed.names[-1] == "noise.sigma"
    sigma = completed.samples[:, -1]
    joint = PosteriorTarget(model)
    scale = np.sqrt(model.sum_squares(theta) / (3 * model.n_points))
    peak = joint.log_prob(np.append(theta, scale))

    def density(s):
        return np.exp(joint.log_prob(np.append(theta, s)) - peak)

    total = integrate.quad(density, 0.2 * scale, 5 * scale)[0]
    cdf = np.vectorize(lambda s: integrate.quad(density, 0.2 * scale, s)[0] / total)
    assert stats.kstest(np.sort(sigma)[::20], cdf).pvalue > 0.01
    np.testing.assert_allclose(completed.log_prob, joint.log_prob_many(completed.samples))
