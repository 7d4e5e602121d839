"""Speed of the zero-offset posterior and its samplers on the bundled kuka-twin (173 configurations).

Measured in one run: log-posterior evaluations per second (compiled hot path, and the same
posterior evaluated with a Pinocchio loop), the paper's 2e5-step Metropolis chain, and effective
samples per second of paper mode, default mode and emcee. Run from the repository root:

    python benchmarks/bench_posterior.py
"""

from __future__ import annotations

import time
import timeit
from pathlib import Path

import numpy as np
import pinocchio as pin

from remaster import diagnostics, spatial
from remaster.campaigns import folders
from remaster.inference import fit
from remaster.inference.laplace_report import LaplaceReport, laplace_fit, laplace_report
from remaster.inference.model import correction_transforms
from remaster.inference.posterior_sampling import sample
from remaster.inference.posterior_targets import PosteriorTarget
from remaster.robot import kinematics

REPO = Path(__file__).resolve().parents[1]


def per_call(function) -> float:
    timer = timeit.Timer(function)
    loops, _ = timer.autorange()
    return min(timer.repeat(repeat=5, number=loops)) / loops


def pinocchio_log_posterior(model, chain):
    """The same log-posterior with forward kinematics by a Pinocchio loop (the reference)."""
    pin_model = kinematics.pinocchio_model(chain)
    data = pin_model.createData()
    frame = pin_model.getFrameId("flange")

    def log_posterior(theta, sigma):
        every = model.full(theta)
        points = np.empty((model.n_points, 3))
        for i, qi in enumerate(model.q + every[6:]):
            pin.framesForwardKinematics(pin_model, data, qi)
            points[i] = data.oMf[frame].act(model.marker)
        transform = correction_transforms(every[:6]) @ model.t_nr
        residual = model.measured - spatial.transform_points(transform, points)
        energy = float(np.sum(residual**2))
        return -(3 * model.n_points + 2) * np.log(sigma) - energy / (2 * sigma**2)

    return log_posterior


def min_ess_per_second(method, run) -> tuple[float, float, float]:
    started = time.perf_counter()
    chains = run()
    seconds = time.perf_counter() - started
    report = diagnostics.chain_report([c for chain in chains for c in _split(chain)], chains[0].names)
    return (
        seconds,
        float(report[["ess_bulk", "ess_tail"]].min().min()),
        float(report[["ess_bulk", "ess_tail"]].min().min()) / seconds,
    )


def _split(chain):
    walkers = chain.per_walker()
    if walkers.shape[1] >= 4:
        return [walkers[:, : walkers.shape[1] // 2], walkers[:, walkers.shape[1] // 2 :]]
    return [walkers]


def main() -> None:
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-twin", repo_root=REPO)
    sensor = campaign.sensors["motion_capture"]
    registration = fit.register(campaign.chain, sensor)
    model, analysis, excluded = fit.build_model(campaign.chain, sensor, registration.t_nr)
    target = PosteriorTarget(model)
    theta = np.append(np.zeros(len(model.names)), 1e-3)
    reference = pinocchio_log_posterior(model, campaign.chain)
    assert abs(reference(theta[:-1], theta[-1]) - target.log_prob(theta)) < 1e-6 * abs(target.log_prob(theta))

    fast = per_call(lambda: target.log_prob(theta))
    slow = per_call(lambda: reference(theta[:-1], theta[-1]))
    walkers = np.tile(theta, (32, 1))
    batched = per_call(lambda: target.log_prob_many(walkers)) / 32
    print(f"log-posterior, {model.n_points} configurations of the iiwa, one core")
    print(f"  compiled, one vector at a time   {1 / fast:10.0f} evaluations/s  ({fast * 1e6:.1f} us)")
    print(f"  compiled, 32 walkers per call    {1 / batched:10.0f} evaluations/s")
    print(f"  Pinocchio loop                   {1 / slow:10.0f} evaluations/s  (compiled is {slow / fast:.0f}x faster)")

    laplace = LaplaceReport.of(laplace_report(laplace_fit(model), analysis, excluded))
    settings = {
        "paper": {"chains": 2, "samples": 200_000, "burn_in": 175_000, "half_width": 0.0125},
        "default": {"chains": 2, "samples": 40_000, "burn_in": 10_000},
        "emcee": {"walkers": 32, "steps": 6_000, "burn_in": 1_000},
    }
    results = {}
    for method in ("paper", "default", "emcee"):
        rng = np.random.default_rng(7)
        results[method] = min_ess_per_second(method, lambda m=method, r=rng: sample(model, laplace, m, settings[m], r))
    paper_seconds = results["paper"][0] / settings["paper"]["chains"]
    print(f"paper-mode chain of 2e5 steps: {paper_seconds:.2f} s per chain")
    print("method     seconds   min ESS   min ESS/s   vs paper")
    for method, (seconds, ess, rate) in results.items():
        print(f"{method:9s} {seconds:8.2f} {ess:9.0f} {rate:11.1f} {rate / results['paper'][2]:9.0f}x")


if __name__ == "__main__":
    main()
