"""Effective samples per second: the paper's Metropolis vs adaptive Metropolis vs emcee.

The target has the paper's 14 parameters and exactly the paper's posterior form,
sigma^-(3n + 2) exp(-E / 2 sigma^2) with n = 173 points, but a LINEAR measurement model
y = J theta + noise: J (519 x 13) is a random design whose columns are scaled so that the
posterior standard deviations are the paper's motion-capture ones (Tables MLE_zero_offsets and
MLE_other_params), the true values are the paper's estimates and sigma = 0.89 mm. The exact
posterior mean is then known (the OLS fit). Each evaluation also does forward-kinematics-sized
busy work (sines and cosines of 173 x 7 joint angles per parameter vector), so sampler overheads
are measured against a realistic per-call cost.

Two scenarios, each timed from scratch (wall time includes burn-in and the least-squares fit):
  A. from the paper's start (Theta = 0, sigma = 1 mm), every method with 2e5 log_prob
     evaluations (the paper's budget);
  B. the default pipeline: least squares + Laplace first, then a short chain from there.
ESS is the smallest over the 14 parameters; "err" the largest |mean - exact| in posterior sd.

Run: python benchmarks/bench_samplers.py   (numbers go into benchmarks/README.md by hand-run)
"""

from __future__ import annotations

import math
import time

import numpy as np

from remaster import diagnostics
from remaster.inference.least_squares import least_squares_laplace
from remaster.inference.sampling.chains import run_emcee
from remaster.inference.sampling.metropolis import metropolis_adaptive, metropolis_paper
from remaster.inference.sampling.target import Chain

MM, DEG = 1e-3, math.pi / 180
N_POINTS = 173
K = 3 * N_POINTS
NAMES = (
    tuple(f"registration.{p}" for p in ("x", "y", "z", "alpha", "beta", "gamma"))
    + tuple(f"zero_offsets.q{j}" for j in range(1, 8))
    + ("noise.sigma",)
)
SCALE = np.array([MM] * 3 + [DEG] * 10 + [MM])
# the paper's motion-capture column: registration then zero-offsets, display units
MEAN = np.array([-2.096, 0.502, 3.311, -0.252, -0.334, -0.960, 0.477, -0.192, 0.139, 0.099, 0.392, -0.114, 0.936])
STD = np.array([0.113, 0.114, 0.0748, 0.006, 0.005, 0.017, 0.012, 0.010, 0.011, 0.013, 0.024, 0.016, 0.039])
SIGMA = 0.890 * MM
BUDGET = 200_000  # log_prob evaluations in scenario A: the paper's chain length


class LinearPaperModel:
    """y = J theta + N(0, sigma^2): residuals for least squares, the paper's posterior as a Target."""

    names, scale = NAMES, SCALE

    def __init__(self, rng: np.random.Generator):
        design = rng.standard_normal((K, 13)) @ (np.eye(13) + 0.4 * rng.standard_normal((13, 13)))
        # scale columns so that sigma sqrt(diag((J^T J)^-1)) is the paper's standard deviations
        self.jacobian = design * (SIGMA * np.sqrt(np.diag(np.linalg.inv(design.T @ design))) / (STD * SCALE[:13]))
        self.y = self.jacobian @ (MEAN * SCALE[:13]) + SIGMA * rng.standard_normal(K)
        self.q = rng.uniform(-np.pi, np.pi, (N_POINTS, 7))
        ols, *_ = np.linalg.lstsq(self.jacobian, self.y, rcond=None)
        sum_squares = float(np.sum((self.y - self.jacobian @ ols) ** 2))
        chi2_dof = K - 13 + 1  # sigma^2 | data ~ SS / chi^2_(k - 13 + 1) under the paper's prior
        sigma_mean = math.sqrt(sum_squares / 2) * math.exp(math.lgamma((chi2_dof - 1) / 2) - math.lgamma(chi2_dof / 2))
        self.exact_mean = np.append(ols, sigma_mean)
        cov = sum_squares / (chi2_dof - 2) * np.linalg.inv(self.jacobian.T @ self.jacobian)
        self.exact_std = np.append(np.sqrt(np.diag(cov)), math.sqrt(sum_squares / (chi2_dof - 2) - sigma_mean**2))

    def _busy(self, thetas: np.ndarray) -> np.ndarray:
        angles = self.q + thetas[:, None, 6:13]  # (m, 173, 7): the shape of batched forward kinematics
        return np.einsum("mij,mij->m", np.cos(angles), np.sin(angles))

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        return self.y - self.jacobian @ theta + 0.0 * self._busy(theta[None])

    def log_prob_many(self, thetas: np.ndarray) -> np.ndarray:
        thetas = np.atleast_2d(thetas)
        r = self.y - thetas[:, :13] @ self.jacobian.T
        sigma = thetas[:, 13]
        safe = np.where(sigma > 0, sigma, 1.0)
        value = -(K + 2) * np.log(safe) - np.einsum("mi,mi->m", r, r) / (2 * safe**2) + 0.0 * self._busy(thetas)
        return np.where(sigma > 0, value, -np.inf)

    def log_prob(self, theta: np.ndarray) -> float:
        return float(self.log_prob_many(theta[None])[0])


def per_call_seconds(function, argument) -> float:
    start, calls = time.perf_counter(), 0
    while time.perf_counter() - start < 0.5:
        function(argument)
        calls += 1
    return (time.perf_counter() - start) / calls


def report(label: str, seconds: float, chain: Chain, model: LinearPaperModel, baseline: float | None):
    table = diagnostics.chain_report([chain])
    ess = float(table[["ess_bulk", "ess_tail"]].min().min())
    error = float(np.max(np.abs(table["mean"].to_numpy() - model.exact_mean) / model.exact_std))
    rate = ess / seconds
    ratio = f"{rate / baseline:7.1f}x" if baseline else "    1.0x"
    print(
        f"{label:52s} {seconds:6.2f} {chain.acceptance_rate:6.3f} {ess:8.1f} {rate:8.1f} {ratio} "
        f"{error:5.2f}  {bool(table['tau_reliable'].all())}"
    )
    return rate


def main() -> None:
    model = LinearPaperModel(np.random.default_rng(2018))
    start = np.append(np.zeros(13), 1.0 * MM)  # the paper's start
    print(
        f"log_prob: {per_call_seconds(model.log_prob, start) * 1e6:.1f} us per single call, "
        f"{per_call_seconds(model.log_prob_many, np.repeat(start[None], 32, 0)) * 1e6:.1f} us per call of 32"
    )
    print(
        f"{'method':52s} {'time s':>6s} {'accept':>6s} {'min ESS':>8s} {'ESS/s':>8s} {'vs paper':>8s} "
        f"{'err':>5s}  tau reliable"
    )
    runs = {
        "A paper: 2e5 steps, keep the last 2.5e4": lambda rng: metropolis_paper(
            model, rng, start, n_samples=BUDGET, burn_in=175_000
        ),
        "A adaptive: 2e5 steps, burn-in 5e4": lambda rng: metropolis_adaptive(
            model, rng, start, n_samples=BUDGET, burn_in=50_000
        ),
        "A emcee: 32 walkers x 6250 steps, burn-in 2500": lambda rng: run_emcee(
            model, rng, start, 0.01 * SCALE, n_walkers=32, n_steps=BUDGET // 32, burn_in=2_500
        ),
    }
    baseline = None
    for label, run in runs.items():
        begin = time.perf_counter()
        chain = run(np.random.default_rng(7))
        rate = report(label, time.perf_counter() - begin, chain, model, baseline)
        baseline = baseline or rate

    def laplace_then(sampler):
        begin = time.perf_counter()
        fit = least_squares_laplace(model.residuals, np.zeros(13), SCALE[:13], names=NAMES[:13])
        chain = sampler(fit)
        return time.perf_counter() - begin, chain

    pipeline = {
        "B Laplace + adaptive: 3e4 steps, burn-in 5e3": lambda fit: metropolis_adaptive(
            model, np.random.default_rng(7), fit.theta_start, fit.full_covariance(), n_samples=30_000, burn_in=5_000
        ),
        "B Laplace + emcee: 32 walkers x 1500 steps, burn-in 300": lambda fit: run_emcee(
            model,
            np.random.default_rng(7),
            fit.theta_start,
            np.sqrt(np.diag(fit.full_covariance())),
            n_walkers=32,
            n_steps=1_500,
            burn_in=300,
        ),
    }
    for label, sampler in pipeline.items():
        seconds, chain = laplace_then(sampler)
        report(label, seconds, chain, model, baseline)


if __name__ == "__main__":
    main()
