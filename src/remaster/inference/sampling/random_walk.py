"""The random-walk Metropolis core that the paper's and the adaptive sampler share (`metropolis`),
and the other samplers' checks of a start and of step counts.

A walker is advanced a block of steps at a time: its increments and log-uniforms are drawn
vectorised and the Python loop (or the model's compiled `walk_block`) only accepts or rejects.
Every random draw comes from the `numpy.random.Generator` passed in: the same seed gives
byte-identical chains.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .target import SamplingError, Target

BLOCK = 4096  # random draws are made this many steps at a time: vectorised, bounded memory
PROGRESS_REPORTS = 10  # progress is reported about every 10 % of the steps


@dataclass
class _Walker:
    """Current state of a single random-walk chain."""

    theta: np.ndarray
    log_prob: float


class _Progress:
    """Calls progress(step, n_steps, acceptance) each time another ~10 % of the steps is done."""

    def __init__(self, callback, n_steps: int):
        self.callback, self.n_steps = callback, n_steps
        self.done = self.accepted = 0
        self.k = 1
        self.next_report = math.ceil(n_steps / PROGRESS_REPORTS)

    def add(self, steps: int, accepted: int) -> None:
        self.done += steps
        self.accepted += accepted
        if self.callback is not None and self.done >= self.next_report:
            self.callback(self.done, self.n_steps, self.accepted / self.done)
            while self.next_report <= self.done:
                self.k += 1
                self.next_report = math.ceil(self.k * self.n_steps / PROGRESS_REPORTS)


def _start(target: Target, start) -> _Walker:
    theta = np.array(start, dtype=float)
    if theta.shape != (len(target.names),):
        raise SamplingError(
            f"start must have shape ({len(target.names)},) for parameters {list(target.names)}, got {theta.shape}"
        )
    lp = float(target.log_prob(theta))
    if not np.isfinite(lp):
        values = ", ".join(f"{n}={v:.6g}" for n, v in zip(target.names, theta))
        raise SamplingError(
            f"log_prob(start) = {lp}: the start is outside the support "
            f"(noise.sigma must be > 0) or the model fails there; start: {values}"
        )
    return _Walker(theta, lp)


def _walk(
    target: Target,
    rng: np.random.Generator,
    walker: _Walker,
    n_steps: int,
    draw_steps: Callable[[np.random.Generator, int], np.ndarray],
    store: bool,
    progress: _Progress,
    thin: int = 1,
) -> tuple[np.ndarray | None, np.ndarray | None, int]:
    """Advance `walker` in place by n_steps Metropolis steps with symmetric increments.

    draw_steps(rng, m) -> (m, P) increments in SI. Increments and log-uniforms are drawn a block
    at a time so the Python loop does only the accept/reject; with a symmetric proposal the
    acceptance ratio is the posterior ratio (eq. acceptance_ratio), compared in logs to avoid the
    under/overflow of sigma^-(3n+2). Returns (samples (n_steps, P), log_probs (n_steps,)) when
    `store`, else (None, None), and the number of accepted proposals. With thin > 1 only every
    thin-th state is stored (the random draws, hence the chain, are the same whatever thin is).
    A target with a `walk_block` (the paper's model: `BlockModel.metropolis_block`) runs each
    block's accept/reject loop compiled, on the same draws: the same chain to the bit.
    """
    p = len(walker.theta)
    stored = -(-n_steps // thin)
    samples = np.empty((stored, p)) if store else None
    log_probs = np.empty(stored) if store else None
    log_prob = target.log_prob
    walk_block = getattr(target, "walk_block", None)
    theta, lp = walker.theta, walker.log_prob
    accepted_total = 0
    for begin in range(0, n_steps, BLOCK):
        m = min(BLOCK, n_steps - begin)
        steps = draw_steps(rng, m)
        # log(0) = -inf accepts any finite proposal; rng.random is in [0, 1), fine either way.
        with np.errstate(divide="ignore"):
            log_u = np.log(rng.random(m))
        if walk_block is not None:
            states, lps, accepted, nan_at = walk_block(theta, lp, steps, log_u)
            if nan_at >= 0:
                _nan_error((states[nan_at - 1] if nan_at else theta) + steps[nan_at])
            if store:
                kept = np.flatnonzero((begin + np.arange(m)) % thin == 0)
                samples[(begin + kept) // thin] = states[kept]
                log_probs[(begin + kept) // thin] = lps[kept]
            theta, lp = states[-1].copy(), float(lps[-1])
        else:
            accepted = 0
            log_u = log_u.tolist()
            for i in range(m):
                proposal = theta + steps[i]
                lp_proposal = log_prob(proposal)
                if lp_proposal != lp_proposal:  # NaN: a model bug, not a rejection
                    _nan_error(proposal)
                if log_u[i] < lp_proposal - lp:
                    theta, lp = proposal, lp_proposal
                    accepted += 1
                if store and (begin + i) % thin == 0:
                    samples[(begin + i) // thin] = theta
                    log_probs[(begin + i) // thin] = lp
        accepted_total += accepted
        progress.add(m, accepted)
    walker.theta, walker.log_prob = theta, float(lp)
    return samples, log_probs, accepted_total


def _nan_error(proposal: np.ndarray):
    values = ", ".join(f"{v:.6g}" for v in proposal)
    raise SamplingError(f"log_prob returned NaN at theta = [{values}]")


def _check_counts(n_samples: int, burn_in: int) -> int:
    if not 0 <= burn_in < n_samples:
        raise ValueError(f"need 0 <= burn_in < n_samples, got burn_in={burn_in}, n_samples={n_samples}")
    return n_samples - burn_in


def _uniform_steps(half_widths: np.ndarray):
    def draw(rng: np.random.Generator, m: int) -> np.ndarray:
        return rng.uniform(-1.0, 1.0, (m, len(half_widths))) * half_widths

    return draw


def _gaussian_steps(covariance: np.ndarray):
    factor = np.linalg.cholesky(covariance)

    def draw(rng: np.random.Generator, m: int) -> np.ndarray:
        return rng.standard_normal((m, len(factor))) @ factor.T

    return draw
