"""The residual GP's evidence against independent noise (`remaster.inference.gp.evidence_gain`)
against known answers: the iid evidence's integral over log sigma, iid noise (no gain) and a smooth
function of one joint (a clear gain), and the DTC likelihood's wrong sign where the exact one is right."""

import math

import numpy as np
import pytest

from remaster.inference.gp import evidence_gain, likelihood, residual
from remaster.inference.gp.kernels import Hyperparameters

NOISE = 3e-5
THRESHOLD = 5.0  # loop_closure/min_log_evidence_gain's default


def readings(rng, n, joints=6, spread=1.5):
    return rng.uniform(-spread, spread, (n, joints))


def test_the_iid_evidence_is_the_integral_over_log_sigma():
    """Known answer: with Jeffreys' prior the integral over u = log sigma of L is closed-form,
    1/2 Gamma(k/2) (pi SS)^(-k/2); Laplace is within 1/(6k) relative of it."""
    rng = np.random.default_rng(3)
    y = rng.normal(0.0, NOISE, (200, 3))
    k, ss = y.size, float(np.sum(y**2))
    closed = math.log(0.5) + math.lgamma(k / 2) - 0.5 * k * math.log(math.pi * ss)
    assert evidence_gain.iid_log_evidence(y) == pytest.approx(closed, abs=0.01)


@pytest.fixture(scope="module")
def noise_only():
    gains = []
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        q = readings(rng, 200, 4)
        y = rng.normal(0.0, NOISE, (len(q), 3))
        hyper = residual.fit_hyperparameters(q, y, subset=200)
        gains.append(evidence_gain.log_evidence_gain(q, y, hyper, mode_rows=200))
    return gains


def test_pure_noise_gives_no_gain(noise_only):
    false_additions = sum(e.gain > THRESHOLD for e in noise_only)
    assert false_additions == 0, [e.gain for e in noise_only]
    assert all(e.method == "exact" for e in noise_only)


def test_a_smooth_function_of_one_joint_gives_a_clear_gain():
    rng = np.random.default_rng(11)
    q = readings(rng, 300)
    y = 4e-5 * np.column_stack([np.sin(2 * q[:, 1]), np.cos(3 * q[:, 1]), np.sin(q[:, 1])])
    y = y + rng.normal(0.0, NOISE, y.shape)
    hyper = residual.fit_hyperparameters(q, y, subset=300)
    scored = evidence_gain.log_evidence_gain(q, y, hyper, mode_rows=300)
    assert scored.gain > 10 * THRESHOLD
    relevance = residual.relevance(scored.mode, q)
    assert np.argmax(relevance) == 1
    # above exact_rows the bound takes over, and it is below the exact value
    bounded = evidence_gain.log_evidence_gain(q, y, hyper, exact_rows=100, inducing=100, mode_rows=300)
    assert bounded.method == "titsias"
    assert THRESHOLD < bounded.gain <= scored.gain


def test_the_dtc_likelihood_can_say_no_where_the_exact_one_says_yes():
    """Why DTC's likelihood was replaced, its sign: a residual that varies faster than the inducing inputs are spaced;
    DTC (at the same hyperparameters, through 6 inducing inputs) puts the variance it cannot
    represent into the noise and falls below iid noise, the exact likelihood is far above."""
    rng = np.random.default_rng(12)
    q = readings(rng, 400, 2, 2.0)
    y = 3e-5 * np.sin(8 * q[:, [0, 0, 0]] + np.array([0.0, 1.0, 2.0])) + rng.normal(0.0, NOISE, (len(q), 3))
    hyper = Hyperparameters(np.array([0.15, np.inf]), 3e-5, NOISE)
    price = 0.5 * 2 * math.log(y.size)
    iid = likelihood.iid_log_likelihood(y)
    dtc = residual.ResidualGP(q, y, hyper, inducing=6).log_likelihood - iid - price
    exact = likelihood.exact_log_likelihood(q, y, hyper) - iid - price
    assert dtc < 0 < exact
    scored = evidence_gain.log_evidence_gain(q, y, hyper, inducing=6)
    assert scored.gain > THRESHOLD
