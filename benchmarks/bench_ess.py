"""How many effective samples an emcee ensemble really holds, against what the diagnostics say.

A correlated 13-dimensional Gaussian (the size of a 7-joint zero-offset fit: six registration
parameters, six offsets, sigma) is sampled by emcee's ensemble (32 walkers, the fit's default) from
many seeds. The true effective sample size of a run's posterior mean is var(x) / var(mean over
seeds); beside it, the mean over seeds of what `diagnostics.chain_report` states (arviz-stats' bulk
ESS, every walker a chain) and what emcee's own integrated autocorrelation time gives (the estimator
remaster used before, n W / tau). An estimate above the truth makes the MCSE too small and the
convergence criterion too easy.

Writes benchmarks/results/ess.json and ess.md. Run from the repository root:
    .venv/bin/python benchmarks/bench_ess.py [--seeds N]
"""

from __future__ import annotations

import argparse
import json
import warnings
from datetime import date
from pathlib import Path

import emcee
import numpy as np

from remaster import diagnostics

RESULTS = Path(__file__).resolve().parent / "results"
PARAMETERS, WALKERS, BURN_IN = 13, 32, 300


def target(rng: np.random.Generator):
    """(covariance (P, P), vectorised log density) of a random correlated Gaussian."""
    a = rng.standard_normal((PARAMETERS, PARAMETERS))
    covariance = a @ a.T / PARAMETERS + 0.05 * np.eye(PARAMETERS)
    precision = np.linalg.inv(covariance)
    return covariance, lambda x: -0.5 * np.einsum("ij,jk,ik->i", x, precision, x)


def one_run(covariance, log_density, kept: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean (P,), stated ESS (P,), emcee's n W / tau (P,)) of one ensemble run."""
    rng = np.random.default_rng(seed)
    start = 0.5 * rng.multivariate_normal(np.zeros(PARAMETERS), covariance, WALKERS)
    sampler = emcee.EnsembleSampler(WALKERS, PARAMETERS, log_density, vectorize=True)
    sampler._random = np.random.RandomState(seed)  # emcee draws from its own RandomState: seeded here
    sampler.run_mcmc(start, BURN_IN + kept)
    x = sampler.get_chain(discard=BURN_IN)  # (kept, W, P)
    half = WALKERS // 2
    stated = diagnostics.chain_report([x[:, :half], x[:, half:]])["ess_bulk"].to_numpy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        emcee_ess = kept * WALKERS / emcee.autocorr.integrated_time(x, quiet=True)
    return x.reshape(-1, PARAMETERS).mean(axis=0), stated, emcee_ess


def measure(kept: int, seeds: int) -> dict:
    covariance, log_density = target(np.random.default_rng(0))
    runs = [one_run(covariance, log_density, kept, 1000 + s) for s in range(seeds)]
    means = np.array([r[0] for r in runs]) / np.sqrt(np.diag(covariance))
    true = 1.0 / means.var(axis=0, ddof=1)
    stated = np.mean([r[1] for r in runs], axis=0)
    old = np.mean([r[2] for r in runs], axis=0)
    return {
        "kept_steps": kept,
        "true_ess_median": float(np.median(true)),
        "stated_ess_median": float(np.median(stated)),
        "emcee_tau_ess_median": float(np.median(old)),
        "stated_over_true": float(np.median(stated / true)),
        "emcee_tau_over_true": float(np.median(old / true)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100)
    args = parser.parse_args()
    rows = [measure(kept, args.seeds) for kept in (500, 1000, 2000)]
    record = {"date": date.today().isoformat(), "seeds": args.seeds, "walkers": WALKERS, "rows": rows}
    # the true ESS of one run is estimated from `seeds` means: its relative sd is about sqrt(2 / seeds)
    record["true_ess_relative_sd"] = float(np.sqrt(2 / args.seeds))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "ess.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    lines = [
        f"Measured {record['date']} by `bench_ess.py`: emcee, {WALKERS} walkers, a {PARAMETERS}-dimensional "
        f"correlated Gaussian, {args.seeds} seeds per row (the true ESS to about "
        f"{100 * record['true_ess_relative_sd']:.0f} %), medians over parameters.",
        "",
        "| kept steps | true ESS | stated (arviz-stats bulk) | stated / true | emcee's n W / tau | that / true |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['kept_steps']} | {r['true_ess_median']:.0f} | {r['stated_ess_median']:.0f} | "
            f"{r['stated_over_true']:.2f} | {r['emcee_tau_ess_median']:.0f} | {r['emcee_tau_over_true']:.2f} |"
        )
    (RESULTS / "ess.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
