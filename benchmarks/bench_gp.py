"""The residual GP at 1k, 3k and 10k configurations: wall time of each step on this machine, and
what the approximation costs against the exact GP.

A smooth residual of joints 2 and 4 (0.1-0.3 mm) plus 0.02 mm noise per axis, 7 joints (one never
turned). Steps: hyperparameters (exact marginal likelihood on `SUBSET` evenly spaced rows),
conditioning on every row through `INDUCING` inducing inputs (DTC), the loop's candidate (both,
plus 5 pose-like folds of cross-validation). Accuracy: RMS error of the mean against the true
residual at 2000 new configurations, per axis; at 3k also the exact GP (all rows, O(n^3)) with
the same hyperparameters.

Run from the repository root: python benchmarks/bench_gp.py [sizes...]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from remaster.inference.gp import kernels, loop_candidate, residual

NOISE = 2e-5


def truth(q):
    return np.column_stack([3e-4 * np.sin(2 * q[:, 1]), 2e-4 * np.cos(q[:, 3] + q[:, 1]), 1e-4 * np.sin(3 * q[:, 3])])


def configurations(rng, n):
    q = rng.uniform(-2.0, 2.0, (n, 7))
    q[:, 2] = 0.0
    return q


def main(sizes) -> None:
    rng = np.random.default_rng(0)
    new = configurations(rng, 2000)
    print(f"{'rows':>6} {'hyper s':>8} {'condition s':>11} {'candidate s':>11} {'mean RMS um':>11} {'exact um':>9}")
    for n in sizes:
        q = configurations(rng, n)
        y = truth(q) + rng.normal(0.0, NOISE, (n, 3))
        started = time.perf_counter()
        hyper = residual.fit_hyperparameters(q, y)
        fitted = time.perf_counter()
        gp = residual.ResidualGP(q, y, hyper)
        conditioned = time.perf_counter()
        loop_candidate.fit_and_score(q, y, y, np.arange(n) // 20 % 5)
        scored = time.perf_counter()
        error = np.sqrt(np.mean((gp.mean(new) - truth(new)) ** 2)) * 1e6
        exact = ""
        if n <= 3000:
            cov = kernels.covariance_with_noise(q, hyper)
            mean = kernels.kernel(new, q, hyper) @ np.linalg.solve(cov, y)
            exact = f"{np.sqrt(np.mean((mean - truth(new)) ** 2)) * 1e6:9.2f}"
        print(
            f"{n:6d} {fitted - started:8.1f} {conditioned - fitted:11.2f} {scored - conditioned:11.1f} {error:11.2f} {exact}"
        )


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [1000, 3000, 10000])
