"""Samplers and diagnostics against posteriors with known answers (in the style of emcee's tests).

The main target: a correlated 4-D Gaussian (sub-millimetre widths, like zero-offset posteriors)
times the posterior of a normal's sigma given N data with known mean under the paper's prior,
p(sigma) ~ sigma^-(N+2) exp(-SS / 2 sigma^2), so exactly SS / sigma^2 ~ chi^2_{N+1}.
Chains are small: the whole file runs in a few seconds. Every test has a fixed seed.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import signal, stats

from remaster import diagnostics
from remaster.diagnostics import SamplerDisagreement
from remaster.inference.least_squares import NotIdentifiable, least_squares_laplace
from remaster.inference.sampling.chains import run_chains, run_emcee
from remaster.inference.sampling.metropolis import metropolis_adaptive, metropolis_paper
from remaster.inference.sampling.target import CallableTarget, SamplingError

MM = 1e-3
DEG = math.pi / 180
NAMES = ("a", "b", "c", "d", "noise.sigma")
MU = np.array([0.05, -0.02, 0.10, 0.0]) * MM
STD = np.array([0.03, 0.05, 0.02, 0.04]) * MM
CORRELATION = np.array([[1.0, 0.9, 0.3, 0.0], [0.9, 1.0, 0.2, 0.0], [0.3, 0.2, 1.0, -0.5], [0.0, 0.0, -0.5, 1.0]])
COVARIANCE = STD[:, None] * CORRELATION * STD
N_DATA = 60
SS_DATA = N_DATA * (1.0 * MM) ** 2  # sigma about 1 mm
START = np.array([0.0, 0.0, 0.0, 0.0, 1.0 * MM])  # the paper's start: Theta = 0, sigma = 1 mm


def sigma_log_posterior(sigma, n_data, sum_squares):
    """-(N + 2) log sigma - SS / (2 sigma^2), -inf for sigma <= 0 (the paper's eq. posterior)."""
    sigma = np.asarray(sigma, dtype=float)
    safe = np.where(sigma > 0, sigma, 1.0)
    return np.where(sigma > 0, -(n_data + 2) * np.log(safe) - sum_squares / (2 * safe**2), -np.inf)


def exact_sigma(n_data, sum_squares):
    """Exact marginal of sigma: SS / sigma^2 ~ chi^2_{N+1}. Returns (mean, std, cdf)."""
    chi2 = stats.chi2(n_data + 1)
    mean = math.sqrt(sum_squares) * chi2.expect(lambda x: x**-0.5)
    second = sum_squares * chi2.expect(lambda x: 1 / x)
    return mean, math.sqrt(second - mean**2), lambda s: chi2.sf(sum_squares / np.asarray(s) ** 2)


def gaussian_sigma_target(mu=MU, covariance=COVARIANCE, n_data=N_DATA, sum_squares=SS_DATA):
    precision = np.linalg.inv(covariance)
    p = len(mu)

    def many(thetas):
        d = thetas[:, :p] - mu
        return -0.5 * np.einsum("ij,jk,ik->i", d, precision, d) + sigma_log_posterior(thetas[:, p], n_data, sum_squares)

    def one(theta):
        if theta[p] <= 0:
            return -math.inf
        d = theta[:p] - mu
        return -0.5 * d @ precision @ d - (n_data + 2) * math.log(theta[p]) - sum_squares / (2 * theta[p] ** 2)

    names = tuple(f"x{i}" for i in range(p)) + ("noise.sigma",) if p != 4 else NAMES
    return CallableTarget(names, np.full(p + 1, MM), many, one)


@pytest.fixture(scope="module")
def target():
    return gaussian_sigma_target()


def exact_moments():
    sigma_mean, sigma_std, _ = exact_sigma(N_DATA, SS_DATA)
    return np.append(MU, sigma_mean), np.append(STD, sigma_std)


def assert_matches_exact(chains):
    """Means within 4 MCSE, variances within 5 sqrt(2 / ESS), split-R-hat < 1.05."""
    report = diagnostics.chain_report(chains)
    mean, std = exact_moments()
    z = (report["mean"].to_numpy() - mean) / report["mcse"].to_numpy()
    assert np.all(np.abs(z) < 4), f"means off by {z} MCSE"
    variance_error = report["std"].to_numpy() ** 2 / std**2 - 1
    assert np.all(np.abs(variance_error) < 5 * np.sqrt(2 / report["ess_bulk"].to_numpy())), variance_error
    assert np.all(report["rhat"] < 1.05), report["rhat"]
    assert np.all(report[["ess_bulk", "ess_tail"]] > 500)


def thinned_marginal(chains, index):
    """Every ceil(2 tau)-th sample of one parameter, pooled: close enough to independent for KS."""
    out = []
    for chain in chains:
        walkers = chain.per_walker()[:, :, index]
        step = math.ceil(2 * walkers.size / diagnostics.effective_sample_size(walkers[:, :, None])[0])
        out.append(walkers[::step].ravel())
    return np.concatenate(out)


def assert_ks(chains):
    _, _, sigma_cdf = exact_sigma(N_DATA, SS_DATA)
    sigma = thinned_marginal(chains, 4)
    assert stats.kstest(sigma, sigma_cdf).pvalue > 1e-4
    # and a correlated Gaussian coordinate
    b = thinned_marginal(chains, 1)
    assert stats.kstest(b, stats.norm(MU[1], STD[1]).cdf).pvalue > 1e-4


# --------------------------------------------------------------------------------------------
# Samplers against the exact posterior


def test_adaptive_metropolis_matches_exact_posterior(target):
    starts = START + np.array([[0.1, -0.1, 0.1, 0.0, 0.2], [-0.1, 0.1, 0.0, 0.1, -0.2]]) * MM
    chains = run_chains(
        metropolis_adaptive, target, np.random.default_rng(11), 2, starts, n_samples=30_000, burn_in=8_000
    )
    assert_matches_exact(chains)
    assert_ks(chains)
    for chain in chains:
        assert chain.method == "metropolis_adaptive" and chain.samples.shape == (22_000, 5)
        assert 0.15 < chain.acceptance_rate < 0.45  # ~0.25-0.3 expected for 2.38^2/P scaling in 5-D


def test_adaptive_proposal_is_learnt_then_frozen(target):
    chain = metropolis_adaptive(target, np.random.default_rng(3), START, n_samples=25_000, burn_in=20_000)
    exact = np.zeros((5, 5))
    exact[:4, :4] = COVARIANCE
    exact[4, 4] = exact_moments()[1][4] ** 2
    factor = chain.settings["scale_factor"]
    assert 0.5 < factor < 2  # ~1 for a Gaussian once the covariance is right
    learnt = chain.settings["proposal_covariance"] / (factor * 2.38**2 / 5)
    # the learnt covariance matches the posterior's in every direction to within a factor 1.6
    root = np.linalg.cholesky(exact)
    whitened = np.linalg.eigvalsh(np.linalg.solve(root, np.linalg.solve(root, learnt).T))
    assert np.all((whitened > 1 / 1.6) & (whitened < 1.6)), whitened
    assert len(chain.settings["stage_acceptance"]) == 20_000 // chain.settings["stage"]


@pytest.mark.parametrize("factor", [1e-6, 1e6])
def test_adaptive_recovers_from_a_bad_initial_covariance(target, factor):
    """Steps 1000x too small or too large at first: the doubling windows still find the scale."""
    initial = np.diag(np.append(STD, 0.1 * MM) ** 2) * factor
    chain = metropolis_adaptive(target, np.random.default_rng(5), START, initial, n_samples=25_000, burn_in=10_000)
    assert 0.15 < chain.acceptance_rate < 0.45
    assert_matches_exact([chain])


def test_emcee_matches_exact_posterior(target):
    chain = run_emcee(
        target, np.random.default_rng(12), START, np.append(STD, 0.1 * MM), n_walkers=20, n_steps=3_000, burn_in=600
    )
    assert chain.samples.shape == (2_400 * 20, 5) and chain.n_walkers == 20
    assert chain.per_walker().shape == (2_400, 20, 5)
    assert 0.2 < chain.acceptance_rate < 0.8
    assert_matches_exact([chain])
    assert_ks([chain])


def test_paper_metropolis_shapes_and_convergence():
    """The paper's sampler on an easy target, widths comparable with its 0.0125 mm steps."""
    mu, std = np.array([0.03, -0.02]) * MM, np.array([0.01, 0.015]) * MM
    n_data, sum_squares = 5_000, 5_000 * MM**2  # sigma = 1 mm +- 0.01 mm
    easy = gaussian_sigma_target(mu, np.diag(std**2), n_data, sum_squares)
    calls = []
    chain = metropolis_paper(
        easy,
        np.random.default_rng(21),
        [0, 0, MM],
        n_samples=50_000,
        burn_in=20_000,
        progress=lambda *a: calls.append(a),
    )
    assert chain.samples.shape == (30_000, 3) and chain.log_prob.shape == (30_000,)
    assert chain.names == ("x0", "x1", "noise.sigma") and chain.method == "metropolis_paper"
    assert 0.2 < chain.acceptance_rate < 0.9
    np.testing.assert_allclose(chain.settings["proposal_half_widths"], 0.0125 * MM)
    # progress: about every 10 %, ending at the last step, acceptance a fraction
    assert 8 <= len(calls) <= 11 and calls[-1][:2] == (50_000, 50_000)
    assert [c[0] for c in calls] == sorted(c[0] for c in calls) and all(0 < c[2] < 1 for c in calls)
    # uniform proposals never leave a half-width box per step
    assert np.all(np.abs(np.diff(chain.samples, axis=0)) <= 0.0125 * MM + 1e-18)
    report = diagnostics.chain_report([chain])
    sigma_mean = exact_sigma(n_data, sum_squares)[0]
    z = (report["mean"].to_numpy() - np.append(mu, sigma_mean)) / report["mcse"].to_numpy()
    assert np.all(np.abs(z) < 4), z


def small_runs():
    """(label, callable(target, rng)) for every sampler, with tiny step counts."""
    return [
        ("paper", lambda t, rng: metropolis_paper(t, rng, START, n_samples=2_000, burn_in=1_000)),
        ("adaptive", lambda t, rng: metropolis_adaptive(t, rng, START, n_samples=3_000, burn_in=1_000)),
        ("emcee", lambda t, rng: run_emcee(t, rng, START, 0.05 * MM, n_walkers=12, n_steps=300, burn_in=100)),
    ]


@pytest.mark.parametrize("label, run", small_runs(), ids=[r[0] for r in small_runs()])
def test_same_seed_gives_byte_identical_samples(target, label, run):
    global_state = np.random.get_state()[1].copy()
    first, second = run(target, np.random.default_rng(99)), run(target, np.random.default_rng(99))
    other = run(target, np.random.default_rng(100))
    assert first.samples.tobytes() == second.samples.tobytes()
    assert first.log_prob.tobytes() == second.log_prob.tobytes()
    assert first.acceptance_rate == second.acceptance_rate
    assert first.samples.tobytes() != other.samples.tobytes()
    np.testing.assert_array_equal(np.random.get_state()[1], global_state)  # no global seeding


@pytest.mark.parametrize("label, run", small_runs(), ids=[r[0] for r in small_runs()])
def test_stored_log_prob_is_the_target_log_prob(target, label, run):
    chain = run(target, np.random.default_rng(1))
    np.testing.assert_allclose(chain.log_prob, target.log_prob_many(chain.samples), rtol=1e-12)
    assert np.all(chain.samples[:, -1] > 0)


def test_run_chains_uses_independent_reproducible_generators(target):
    def run(seed):
        return run_chains(
            metropolis_adaptive, target, np.random.default_rng(seed), 3, START, n_samples=1_500, burn_in=500
        )

    first, again = run(4), run(4)
    assert len(first) == 3
    assert all(a.samples.tobytes() == b.samples.tobytes() for a, b in zip(first, again))
    assert first[0].samples.tobytes() != first[1].samples.tobytes()  # same start, different streams
    with pytest.raises(ValueError, match="n_chains >= 2"):
        run_chains(metropolis_adaptive, target, np.random.default_rng(0), 1, START)


def test_bad_starts_and_nan_log_prob_are_named(target):
    with pytest.raises(SamplingError, match="noise.sigma"):
        metropolis_paper(target, np.random.default_rng(0), [0, 0, 0, 0, 0.0], n_samples=10, burn_in=0)
    with pytest.raises(SamplingError, match="shape"):
        metropolis_adaptive(target, np.random.default_rng(0), [0, 0, MM], n_samples=10, burn_in=0)
    with pytest.raises(ValueError, match="burn_in"):
        metropolis_paper(target, np.random.default_rng(0), START, n_samples=10, burn_in=10)
    with pytest.raises(ValueError, match="walkers"):
        run_emcee(target, np.random.default_rng(0), START, MM, n_walkers=8, n_steps=10, burn_in=0)
    nan_away = CallableTarget(
        ("x", "noise.sigma"), [MM, MM], lambda t: np.where(t[:, 0] > 0.02 * MM, np.nan, -(t[:, 0] ** 2) / MM**2)
    )
    with pytest.raises(SamplingError, match="NaN"):
        metropolis_paper(nan_away, np.random.default_rng(0), [0, MM], n_samples=5_000, burn_in=0)


def test_chain_summary_names_method_and_parameters(target):
    chain = run_emcee(target, np.random.default_rng(2), START, 0.05 * MM, n_walkers=12, n_steps=200, burn_in=50)
    text = chain.summary()
    assert text.startswith("emcee: 150 kept steps x 12 walker(s)")
    assert all(name in text for name in NAMES)


def test_emcee_runs_on_until_its_criteria_hold_and_no_longer(target):
    """The ensemble doubles its kept steps while `enough` fails (150 -> 300 -> 600 kept steps when
    600 are asked for), stops at max_doublings when it never holds, and without a test keeps its
    first length; the chain is the same ensemble continued, so its first kept steps are the short
    run's."""
    seen = []

    def enough(paths):
        seen.append(paths.shape[0])
        return paths.shape[0] >= 600

    def run(**kw):
        return run_emcee(
            target, np.random.default_rng(3), START, 0.05 * MM, n_walkers=12, n_steps=200, burn_in=50, **kw
        )

    grown = run(enough=enough, max_doublings=5)
    assert seen == [150, 300, 600] and grown.n_steps == 600 and grown.settings["doublings"] == 2
    assert grown.settings["n_steps"] == 650
    capped = run(enough=lambda paths: False, max_doublings=1)
    assert capped.n_steps == 300
    fixed = run()
    assert fixed.n_steps == 150
    np.testing.assert_array_equal(grown.samples[: len(fixed.samples)], fixed.samples)


# --------------------------------------------------------------------------------------------
# Least squares and the Laplace approximation


def linear_problem(seed=7, k=40):
    rng = np.random.default_rng(seed)
    x = np.column_stack([np.ones(k), rng.uniform(-1, 1, k), rng.uniform(0, 2, k)])
    beta = np.array([0.1, -0.3, 2.0]) * MM
    y = x @ beta + 0.05 * MM * rng.standard_normal(k)
    return x, y


def test_laplace_equals_closed_form_ols():
    x, y = linear_problem()
    k, m = x.shape
    scale = np.array([MM, MM, DEG])  # unequal step units must not change the answer
    fit = least_squares_laplace(lambda b: y - x @ b, np.zeros(m), scale, names=("b0", "b1", "b2"))
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    rss = float(np.sum((y - x @ beta) ** 2))
    np.testing.assert_allclose(fit.theta_map, beta, rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(fit.covariance, rss / (k - m) * np.linalg.inv(x.T @ x), rtol=1e-6)
    assert fit.cost == pytest.approx(rss / 2, rel=1e-9)  # scipy's cost is HALF the sum of squares
    assert fit.sigma_map == pytest.approx(math.sqrt(rss / k), rel=1e-9)
    # sigma: exact marginal under the paper's prior, sigma^2 ~ SS / chi^2_{k - m + 1}
    mean, std, _ = exact_sigma(k - m, rss)
    assert fit.sigma_mean == pytest.approx(mean, rel=1e-7)
    assert fit.sigma_std == pytest.approx(std, rel=1e-5)
    assert fit.sigma_std == pytest.approx(fit.sigma_mean / math.sqrt(2 * (k - m + 1)), rel=0.05)  # large-k form
    assert fit.full_covariance().shape == (4, 4) and fit.theta_start[-1] == fit.sigma_map
    # an analytic Jacobian gives the same
    exact_j = least_squares_laplace(lambda b: y - x @ b, np.zeros(m), scale, jacobian=lambda b: -x)
    np.testing.assert_allclose(exact_j.covariance, fit.covariance, rtol=1e-6)


def test_laplace_names_the_undetermined_parameters():
    x, y = linear_problem()
    x = np.column_stack([x, 2 * x[:, 1]])  # b3 duplicates b1
    with pytest.raises(NotIdentifiable, match=r"b1.*b3|b3.*b1") as info:
        least_squares_laplace(lambda b: y - x @ b, np.zeros(4), MM, names=("b0", "b1", "b2", "b3"))
    assert [set(c) for c in info.value.combinations] == [{"b1", "b3"}]
    assert "b0" not in str(info.value).split(":")[-1]
    with pytest.raises(ValueError, match="residuals"):
        least_squares_laplace(lambda b: y[:4] - x[:4, :3] @ b, np.zeros(3), MM)


def test_laplace_restarts_need_rng_and_find_the_global_minimum():
    # two minima: (b - 1)^2 (b + 1)^2 style residuals; the restart from near +1 wins when it is lower
    residuals = lambda b: np.array([(b[0] ** 2 - 1.0) * 10, b[0] - 0.9, 0.01, -0.01, 0.02])  # noqa: E731
    with pytest.raises(ValueError, match="rng"):
        least_squares_laplace(residuals, [-1.0], 1.0, n_restarts=2)
    single = least_squares_laplace(residuals, [-1.0], 1.0)
    multi = least_squares_laplace(
        residuals, [-1.0], 1.0, rng=np.random.default_rng(0), n_restarts=16, restart_spread=3.0
    )
    assert single.theta_map[0] < 0 < multi.theta_map[0] and multi.cost < single.cost


def test_laplace_and_samplers_agree_on_a_linear_model():
    """On a linear model the Laplace means are exact: MCMC must cross-check against them."""
    x, y = linear_problem(seed=8, k=30)
    k, m = x.shape
    names = ("b0", "b1", "b2", "noise.sigma")
    fit = least_squares_laplace(lambda b: y - x @ b, np.zeros(m), MM, names=names[:3])

    def many(thetas):
        r = y - thetas[:, :m] @ x.T
        return sigma_log_posterior(thetas[:, m], k, np.sum(r * r, axis=1))

    posterior = CallableTarget(names, np.full(4, MM), many)
    adaptive = metropolis_adaptive(
        posterior, np.random.default_rng(1), fit.theta_start, fit.full_covariance(), n_samples=25_000, burn_in=3_000
    )
    ensemble = run_emcee(
        posterior,
        np.random.default_rng(2),
        fit.theta_start,
        np.sqrt(np.diag(fit.full_covariance())),
        n_walkers=16,
        n_steps=1_500,
        burn_in=300,
    )
    table = diagnostics.cross_check(
        {
            "laplace": fit.moments(),
            "adaptive": diagnostics.moments([adaptive]),
            "emcee": diagnostics.moments([ensemble]),
        },
        names,
        floor=0.1,
    )
    assert table.attrs["reference"] == "laplace"
    # the exact marginal of b is Student-t: Laplace's s^2 (X^T X)^-1 is its covariance to O(1/k)
    np.testing.assert_allclose(table["std"]["adaptive"], table["std"]["laplace"], rtol=0.12)
    np.testing.assert_allclose(table["std"]["emcee"], table["std"]["laplace"], rtol=0.12)


# --------------------------------------------------------------------------------------------
# Diagnostics


def ar1(rng, phi, n, shape=()):
    """AR(1) with unit marginal variance along axis 0: tau = (1 + phi) / (1 - phi)."""
    noise = rng.standard_normal((n, *shape)) * math.sqrt(1 - phi**2)
    noise[0] = rng.standard_normal(shape)  # start in the stationary distribution
    return signal.lfilter([1.0], [1.0, -phi], noise, axis=0)


def test_ess_of_ar1_chains_is_n_over_tau():
    """AR(1) with coefficient phi: tau = (1 + phi) / (1 - phi), so the ESS of n draws is n / tau,
    for one chain and for an ensemble whose walkers all count."""
    rng = np.random.default_rng(0)
    chain = ar1(rng, 0.8, 200_000, (2,))  # tau = 9
    np.testing.assert_allclose(diagnostics.effective_sample_size(chain), 200_000 / 9.0, rtol=0.1)
    ensemble = ar1(rng, 0.8, 25_000, (8, 2))  # (n, W, P): ESS counts every walker
    np.testing.assert_allclose(diagnostics.effective_sample_size(ensemble), 25_000 * 8 / 9.0, rtol=0.1)
    independent = rng.standard_normal((20_000, 2))
    np.testing.assert_allclose(diagnostics.effective_sample_size(independent, "tail"), 20_000, rtol=0.1)
    # the tail ESS of a correlated chain is below its draws too
    assert np.all(diagnostics.effective_sample_size(chain, "tail") < 200_000 / 3)


def test_ess_equals_arviz_stats_own_geyer_loop_to_the_bit():
    """The ESS's Geyer sequences as array operations give the float arviz-stats' loop gives, on
    chains from independent to a random walk (the paper sampler's), short and long, one to 64
    walkers, ties and 0/1 indicators (the tail ESS's), a NaN and a constant chain."""
    from arviz_stats.base.array import BaseArray

    library, ours = BaseArray(), diagnostics._array_stats()
    rng = np.random.default_rng(7)
    cases = []
    for phi in (0.0, 0.5, 0.9, 0.999, -0.6):
        for chains, draws in ((1, 5), (2, 7), (4, 400), (64, 120), (2, 3000)):
            cases.append(ar1(rng, phi, draws, (chains,)).T.copy())
    cases += [np.round(cases[12]), (cases[17] > 0).astype(float), np.cumsum(rng.standard_normal((4, 5000)), axis=1)]
    with_nan = cases[8].copy()
    with_nan[0, 3] = np.nan
    cases += [with_nan, np.ones((2, 50))]
    for case in cases:
        expected, got = library._ess(case), ours._ess(case)
        assert got == expected or (math.isnan(got) and math.isnan(expected)), (case.shape, expected, got)


def test_mcse_covers_the_spread_of_chain_means():
    """Over 400 seeds, the means of AR(1) chains scatter by the MCSE the report gives (the true
    Monte Carlo error is sqrt(tau / n)), and 95 % of them lie within 1.96 MCSE of the truth."""
    rng = np.random.default_rng(3)
    n, tau = 4_000, (1 + 0.7) / (1 - 0.7)
    chains = ar1(rng, 0.7, n, (400, 1))  # 400 independent chains of n, each its own report
    means = chains.mean(axis=0)[:, 0]
    mcse = np.array([diagnostics.chain_report([chains[:, k]])["mcse"].iloc[0] for k in range(400)])
    np.testing.assert_allclose(np.median(mcse), math.sqrt(tau / n), rtol=0.1)
    np.testing.assert_allclose(means.std(), math.sqrt(tau / n), rtol=0.15)
    inside = np.mean(np.abs(means) <= 1.96 * mcse)
    assert 0.92 <= inside <= 0.98, inside  # a binomial sd is 1.1 % at 400 chains


def test_short_or_stuck_chains_are_flagged_not_raised():
    rng = np.random.default_rng(1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        short = diagnostics.chain_report([ar1(rng, 0.99, 300, (1,))])
        assert not short["tau_reliable"].iloc[0] and np.isfinite(short["tau"].iloc[0])
        stuck = diagnostics.chain_report([np.column_stack([np.ones(500), rng.standard_normal(500)])])
        assert stuck["ess_bulk"].iloc[0] == 1 and stuck["mcse"].iloc[0] == 0 and math.isnan(stuck["rhat"].iloc[0])
        assert list(stuck["tau_reliable"]) == [False, True]
        tiny = diagnostics.chain_report([np.zeros((2, 3))])
        assert tiny["rhat"].isna().all() and not tiny["tau_reliable"].any()


def test_rhat_is_one_on_mixed_chains_and_above_on_separated_drifting_or_scaled_ones():
    rng = np.random.default_rng(2)
    good = [rng.standard_normal((2_000, 3)) for _ in range(4)]
    assert np.all(np.abs(diagnostics.rhat(good) - 1) < 0.01)
    stuck = [good[0], good[1] + 3.0]  # two chains in different places
    assert np.all(diagnostics.rhat(stuck) > 1.1)
    drifting = [good[0] + np.linspace(0, 4, 2_000)[:, None]]  # one chain, still moving: the split catches it
    assert np.all(diagnostics.rhat(drifting) > 1.1)
    # same location, different spread: the classic R-hat misses it, the folded (rank) one does not
    scaled = [good[0], 5 * good[1], good[2], 5 * good[3]]
    assert np.all(diagnostics.rhat(scaled) > 1.05)
    assert np.isnan(diagnostics.rhat([np.zeros((3, 1))])).all()


def test_rhat_flags_unconverged_chains_at_its_stated_rate():
    """Over 200 seeds of four independent, well-mixed chains R-hat stays below 1.01 (Vehtari et al.
    recommend 1.01); one chain started 2 sd off on a slow AR(1) exceeds it nearly always."""
    rng = np.random.default_rng(5)
    mixed = [diagnostics.rhat([ar1(rng, 0.5, 1_000, (1,)) for _ in range(4)])[0] for _ in range(200)]
    assert np.mean(np.array(mixed) > 1.01) < 0.05
    off = []
    for _ in range(200):
        chains = [ar1(rng, 0.99, 1_000, (1,)) for _ in range(4)]
        chains[0] = chains[0] + 2.0 * 0.99 ** np.arange(1_000)[:, None]  # forgets its start over ~100 steps
        off.append(diagnostics.rhat(chains)[0])
    assert np.mean(np.array(off) > 1.01) > 0.9


def test_chain_report_columns(target):
    chains = [
        metropolis_adaptive(target, np.random.default_rng(s), START, n_samples=3_000, burn_in=1_000) for s in (1, 2)
    ]
    report = diagnostics.chain_report(chains)
    assert list(report.index) == list(NAMES) and report.index.name == "parameter"
    assert list(report.columns) == [
        *("mean", "std", "q2.5", "q97.5", "mcse", "ess_bulk", "ess_tail", "rhat", "tau", "tau_reliable")
    ]
    # the MCSE of the mean is std / sqrt(ESS of the mean), close to the bulk ESS on a Gaussian target
    np.testing.assert_allclose(report["mcse"], report["std"] / np.sqrt(report["ess_bulk"]), rtol=0.2)
    assert np.all(report["q2.5"] < report["mean"]) and np.all(report["mean"] < report["q97.5"])


def test_cross_check_raises_when_one_method_is_shifted():
    names = ["x", "y"]
    mean, std = np.array([1.0, 2.0]), np.array([0.1, 0.2])
    results = {
        "reference": (mean, std, np.array([0.005, 0.01])),
        "good": (mean + np.array([0.01, -0.02]), std, np.array([0.005, 0.01])),
        "shifted": (mean + np.array([0.0, 0.2]), std, np.array([0.005, 0.01])),
    }
    with pytest.raises(SamplerDisagreement, match=r"y: shifted .* vs reference") as info:
        diagnostics.cross_check(results, names, floor=0.05)
    z = 0.2 / math.hypot(0.01, 0.01)  # combined Monte Carlo error of the two methods
    assert info.value.offenders == [("y", "shifted", "reference", pytest.approx(z))]
    table = diagnostics.cross_check(results, names, tolerance=None, floor=0.05)
    assert table.loc["y", ("z", "shifted")] == pytest.approx(z) and table.loc["x", ("z", "reference")] == 0
    assert set(table.columns.get_level_values("quantity")) == {"mean", "std", "z"}
    table.attrs.clear()  # attrs can be lost on the way: the reference is then the all-zero z column
    with pytest.raises(SamplerDisagreement, match=r"y: shifted .* vs reference"):
        diagnostics.check_agreement(table, tolerance=4.0)
    del results["shifted"]
    diagnostics.cross_check(results, names, floor=0.05)  # no error
    with pytest.raises(SamplerDisagreement):
        diagnostics.check_agreement(diagnostics.cross_check(results, names, tolerance=None, floor=0.05), tolerance=1.0)


def test_cross_check_floor_when_there_is_no_monte_carlo_error():
    """mcse 0 on both sides (e.g. Laplace vs Laplace): the error is the floor (here 5 %) of the larger std."""
    names, std, zero = ["x"], np.array([1.0]), np.zeros(1)
    close = {"laplace": (np.zeros(1), std, zero), "other": (np.array([0.15]), std, zero)}
    assert diagnostics.cross_check(close, names, floor=0.05).loc["x", ("z", "other")] == pytest.approx(3.0)
    far = {"laplace": (np.zeros(1), std, zero), "other": (np.array([0.3]), std, zero)}
    with pytest.raises(SamplerDisagreement, match="x: other"):
        diagnostics.cross_check(far, names, floor=0.05)
    nan = {"laplace": (np.zeros(1), std, zero), "other": (np.array([np.nan]), std, zero)}
    with pytest.raises(SamplerDisagreement):
        diagnostics.cross_check(nan, names, floor=0.05)
