"""The random-walk Metropolis samplers (each returns a `Chain`):

- `metropolis_paper`: the paper's Metropolis (section Optimization, eq. acceptance_ratio):
  all parameters perturbed at once by U(-0.0125, 0.0125) display units, 2e5 steps, the last
  2.5e4 kept. Kept for reproducing the paper, not for efficiency.
- `metropolis_adaptive`: Gaussian random-walk Metropolis whose covariance, (2.38^2 / P) times
  an estimate of the posterior covariance (times a global factor tuned to the acceptance rate),
  is learnt in stages during burn-in and then frozen, so the kept chain is a plain
  (time-homogeneous) Markov chain.

Step counts: `n_samples` is the total number of iterations INCLUDING burn-in (the paper's "2e5
samples, converged from 1.75e5 on"), so a chain keeps n_samples - burn_in states.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .random_walk import _check_counts, _gaussian_steps, _Progress, _start, _uniform_steps, _walk
from .target import Chain, Target

PAPER_HALF_WIDTH = 0.0125  # display units (mm or deg): the paper's U(-0.0125, 0.0125) proposal
OPTIMAL_RW_SCALE = 2.38**2  # Roberts, Gelman & Gilks (1997): proposal = 2.38^2 / P * posterior covariance
MAX_LOG_LAMBDA = math.log(1e12)  # the adaptive global scale stays within 1e-12 .. 1e12


def metropolis_paper(
    target: Target,
    rng: np.random.Generator,
    start,
    n_samples: int = 200_000,
    burn_in: int = 175_000,
    half_width: float = PAPER_HALF_WIDTH,
    progress: Callable[[int, int, float], None] | None = None,
    trace_every: int = 100,
) -> Chain:
    """The paper's Metropolis: every parameter perturbed at once by U(-h, h) * scale.

    start (P,) SI (paper: Theta = 0, sigma = 1 mm); half_width h in step units (paper 0.0125 mm
    or deg); n_samples total iterations, the first burn_in discarded (paper 2e5 and 1.75e5).
    progress(step, n_samples, acceptance so far) is called about every 10 %. Every trace_every-th
    state of the burn-in is kept in settings["burn_in_trace"] (k, P), for the trace figure.
    """
    scale = np.asarray(target.scale, dtype=float)
    settings = {
        "n_samples": n_samples,
        "burn_in": burn_in,
        "half_width": half_width,
        "proposal_half_widths": half_width * scale,
    }
    kept = _check_counts(n_samples, burn_in)
    walker = _start(target, start)
    draw = _uniform_steps(half_width * scale)
    tracker = _Progress(progress, n_samples)
    # the burn-in is stored thinned only: its trace shows where the chain travelled
    settings["burn_in_trace"], _, _ = _walk(target, rng, walker, burn_in, draw, True, tracker, thin=trace_every)
    settings["trace_every"] = trace_every
    samples, log_probs, accepted = _walk(target, rng, walker, kept, draw, True, tracker)
    return Chain(samples, log_probs, accepted / kept, tuple(target.names), "metropolis_paper", settings)


class _WindowMoments:
    """Sample covariance over the stationary part of the latest half of the burn-in so far.

    The window is the latest half of the stages, minus any stage still in the transient from the
    start: one whose mean log-posterior is more than 3 sqrt(P / 2) below the level of the latest
    eighth (in a P-dimensional, roughly Gaussian posterior the log-density varies with standard
    deviation sqrt(P / 2)). States on the way in from a far start would inflate the covariance
    along the drift; a window shorter than half would be noisier once stationary. Sums per stage
    make each estimate O(P^2) whatever the burn-in length; they are taken about the start point so
    that a mean far from zero does not cancel digits away.
    """

    def __init__(self, shift: np.ndarray):
        self.shift = shift
        p = len(shift)
        self.count, self.first, self.second, self.moves = [0], [np.zeros(p)], [np.zeros((p, p))], [0]
        self.level = []  # mean log-posterior of each stage

    def add(self, samples: np.ndarray, log_probs: np.ndarray, accepted: int) -> None:
        x = samples - self.shift
        self.count.append(self.count[-1] + len(x))
        self.first.append(self.first[-1] + x.sum(axis=0))
        self.second.append(self.second[-1] + x.T @ x)
        self.moves.append(self.moves[-1] + accepted)
        self.level.append(float(np.mean(log_probs)))

    def window(self) -> int:
        """First stage of the estimation window."""
        end = len(self.level)
        level = np.array(self.level)
        recent = level[end - max(1, end // 8) :].mean()
        low = np.flatnonzero(level[end // 2 :] < recent - 3 * math.sqrt(len(self.shift) / 2))
        return min(end // 2 + (low[-1] + 1 if low.size else 0), end - 1)

    def covariance(self) -> tuple[np.ndarray, int]:
        """(covariance (P, P), accepted moves) over the window (at least the last stage)."""
        end, begin = len(self.level), self.window()
        n = self.count[end] - self.count[begin]
        mean = (self.first[end] - self.first[begin]) / n
        second = (self.second[end] - self.second[begin]) / n
        return (second - np.outer(mean, mean)) * n / max(n - 1, 1), self.moves[end] - self.moves[begin]


def _blended(
    previous: np.ndarray, prior: np.ndarray, prior_weight: float, estimate: np.ndarray, moves: int
) -> np.ndarray:
    """(w0 t C0 + n_eff S) / (w0 + n_eff): the window estimate S shrunk towards the SHAPE of C0.

    n_eff = accepted moves / P approximates the effective sample size of a well-tuned random walk
    (acceptance ~0.23, tau ~3.3 P for Gaussian targets), so a sticky window counts for little and
    a good initial covariance (a Laplace one) is not replaced by a noisy short-window estimate.
    t = tr(C0^-1 S) / P rescales C0 to the size of S: C0 lends its shape, not its magnitude,
    so an initial covariance that is right in shape but 1e6 times too large is not a trap.
    A window without moves, or a blend that is not positive definite, keeps `previous`.
    """
    if moves == 0:
        return previous
    t = np.trace(np.linalg.solve(prior, estimate)) / len(prior)
    n_eff = moves / len(prior)
    blend = (prior_weight * t * prior + n_eff * estimate) / (prior_weight + n_eff)
    try:
        np.linalg.cholesky(blend)
    except np.linalg.LinAlgError:  # S indefinite by round-off when (near) singular
        return previous
    return blend


def metropolis_adaptive(
    target: Target,
    rng: np.random.Generator,
    start,
    covariance=None,
    n_samples: int = 60_000,
    burn_in: int = 20_000,
    initial_std: float = PAPER_HALF_WIDTH,
    covariance_weight: float | None = None,
    stage: int | None = None,
    target_acceptance: float = 0.234,
    progress: Callable[[int, int, float], None] | None = None,
) -> Chain:
    """Gaussian random-walk Metropolis, proposal N(0, lambda 2.38^2 / P C), adapted during burn-in.

    start (P,) SI; covariance (P, P) SI, the initial C0 (e.g. `LaplaceResult.full_covariance()`),
    default diag((initial_std * scale)^2). covariance_weight: how many effective samples C0 is
    worth, default 10 P when a covariance is given (it is information) and 1 when not (a guess).
    Burn-in runs in stages of `stage` steps (default max(100, 10 P)). After each stage
    (Haario et al. 2001 with global scaling, Andrieu & Thoms 2008 sec. 5.1.1, per stage):
      C <- the sample covariance of the latest half of the burn-in so far, without the stages
           still in the transient from the start (`_WindowMoments`), shrunk towards the shape of
           C0 by covariance_weight against the window's effective size (`_blended`);
      log lambda += 2 (stage acceptance - target_acceptance): lambda = 1 for a Gaussian posterior
           once C is right; it shrinks the steps while C is still inflated by the drift from a
           far start, which is what lets the chain reach the posterior and C converge.
    At the end of burn-in the proposal is FROZEN: the kept n_samples - burn_in states are a
    time-homogeneous Markov chain with the posterior as its stationary distribution (adapting on
    would need diminishing-adaptation arguments). settings["proposal_covariance"] is the frozen
    proposal, settings["scale_factor"] the final lambda.
    """
    p = len(target.names)
    scale = np.asarray(target.scale, dtype=float)
    kept = _check_counts(n_samples, burn_in)
    if covariance is None:
        prior = np.diag((initial_std * scale) ** 2)
        weight = 1.0 if covariance_weight is None else covariance_weight
    else:
        prior = np.array(covariance, dtype=float)
        if prior.shape != (p, p):
            raise ValueError(f"covariance must be ({p}, {p}), got {prior.shape}")
        try:
            np.linalg.cholesky(prior)
        except np.linalg.LinAlgError:
            raise ValueError("covariance must be symmetric positive definite") from None
        weight = 10.0 * p if covariance_weight is None else covariance_weight
    if weight <= 0:
        raise ValueError(f"covariance_weight must be > 0, got {weight}")
    walker = _start(target, start)
    tracker = _Progress(progress, n_samples)
    stage = stage or max(100, 10 * p)
    moments = _WindowMoments(walker.theta.copy())
    c, log_lambda, acceptance = prior, 0.0, []
    for begin in range(0, burn_in, stage):
        size = min(stage, burn_in - begin)
        proposal = math.exp(log_lambda) * OPTIMAL_RW_SCALE / p * c
        samples, log_probs, accepted = _walk(target, rng, walker, size, _gaussian_steps(proposal), True, tracker)
        acceptance.append(accepted / size)
        # bounded: a chain that never moves must not drive the proposal to underflow
        log_lambda += 2.0 * (accepted / size - target_acceptance)
        log_lambda = min(max(log_lambda, -MAX_LOG_LAMBDA), MAX_LOG_LAMBDA)
        moments.add(samples, log_probs, accepted)
        estimate, moves = moments.covariance()
        c = _blended(c, prior, weight, estimate, moves)
    proposal = math.exp(log_lambda) * OPTIMAL_RW_SCALE / p * c
    samples, log_probs, accepted = _walk(target, rng, walker, kept, _gaussian_steps(proposal), True, tracker)
    settings = {
        "n_samples": n_samples,
        "burn_in": burn_in,
        "stage": stage,
        "stage_acceptance": np.array(acceptance),
        "covariance_weight": weight,
        "scale_factor": math.exp(log_lambda),
        "proposal_covariance": proposal,
    }
    return Chain(samples, log_probs, accepted / kept, tuple(target.names), "metropolis_adaptive", settings)
