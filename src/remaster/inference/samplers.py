"""Posterior samplers and the least-squares/Laplace approximation, against a generic target.

Nothing here knows about robots. A `Target` is P named parameters (the last one, by convention,
"noise.sigma" > 0), a log-posterior that is -inf outside the support, and `scale` (P,): the SI size
of each parameter's natural step unit (1 mm = 1e-3 for lengths, 1 deg = pi/180 for angles).

Samplers (each returns a `Chain`):

- `metropolis_paper`: the paper's Metropolis (section Optimization, eq. acceptance_ratio):
  all parameters perturbed at once by U(-0.0125, 0.0125) display units, 2e5 steps, the last
  2.5e4 kept. Kept for reproducing the paper, not for efficiency.
- `metropolis_adaptive`: Gaussian random-walk Metropolis whose covariance, (2.38^2 / P) times
  an estimate of the posterior covariance (times a global factor tuned to the acceptance rate),
  is learnt in stages during burn-in and then frozen, so the kept chain is a plain
  (time-homogeneous) Markov chain.
- `run_emcee`: emcee's affine-invariant ensemble, vectorised over walkers.
- `metropolis_independence`: independence Metropolis-Hastings with a Student-t proposal from a
  Laplace approximation, for posteriors close to it (the loop closure's extended models).

Step counts: `n_samples` / `n_steps` is the total number of iterations INCLUDING burn-in (the
paper's "2e5 samples, converged from 1.75e5 on"), so a chain keeps n_samples - burn_in states
(times n_walkers for emcee).

Every random draw comes from the `numpy.random.Generator` passed in: the same seed gives
byte-identical chains.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)

from ..errors import RemasterError
from .identifiability import RCOND, undetermined_directions  # the one test: the analysis's and the fit's

PAPER_HALF_WIDTH = 0.0125  # display units (mm or deg): the paper's U(-0.0125, 0.0125) proposal
OPTIMAL_RW_SCALE = 2.38**2  # Roberts, Gelman & Gilks (1997): proposal = 2.38^2 / P * posterior covariance
BLOCK = 4096  # random draws are made this many steps at a time: vectorised, bounded memory
PROGRESS_REPORTS = 10  # progress is reported about every 10 % of the steps
MAX_LOG_LAMBDA = math.log(1e12)  # the adaptive global scale stays within 1e-12 .. 1e12


class SamplingError(RemasterError, ValueError):
    """A sampler cannot start or continue: a start outside the support, a NaN log-posterior."""


class NotIdentifiable(RemasterError, ValueError):
    """The data do not determine some parameter combinations: J^T J is (numerically) singular.

    `combinations` lists, per undetermined direction, {parameter name: weight} of its main parts.
    """

    def __init__(self, message: str, combinations: list[dict[str, float]]):
        self.combinations = combinations
        super().__init__(message)


# --------------------------------------------------------------------------------------------
# The target interface


@runtime_checkable
class Target(Protocol):
    """What the samplers need of a posterior (e.g. `fit.PosteriorTarget`); nothing about robots.

    names: P parameter names, the last "noise.sigma"; scale: (P,) SI size of one step unit;
    log_prob(theta (P,)) -> float; log_prob_many(thetas (m, P)) -> (m,); -inf outside the support.
    """

    names: tuple[str, ...]
    scale: np.ndarray

    def log_prob(self, theta: np.ndarray) -> float: ...

    def log_prob_many(self, thetas: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class CallableTarget:
    """A `Target` from plain functions. `one` defaults to `many` on a single row.

    many: thetas (m, P) -> (m,) log-posterior; one: theta (P,) -> float (optional, faster for
    single-chain Metropolis when given).
    """

    names: tuple[str, ...]
    scale: np.ndarray
    many: Callable[[np.ndarray], np.ndarray]
    one: Callable[[np.ndarray], float] | None = None

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(self.names))
        scale = np.asarray(self.scale, dtype=float)
        if scale.shape != (len(self.names),) or not np.all(scale > 0):
            raise ValueError(f"scale must be ({len(self.names)},) and positive, got {scale!r}")
        object.__setattr__(self, "scale", scale)

    def log_prob(self, theta) -> float:
        if self.one is not None:
            return float(self.one(theta))
        return float(self.many(np.asarray(theta, dtype=float)[None, :])[0])

    def log_prob_many(self, thetas) -> np.ndarray:
        return np.asarray(self.many(np.asarray(thetas, dtype=float)), dtype=float)


# --------------------------------------------------------------------------------------------
# Results


@dataclass(frozen=True, eq=False)
class Chain:
    """One sampler run after burn-in.

    samples: (n, P) SI, in time order; for emcee step-major over walkers, i.e.
    samples.reshape(n_steps, n_walkers, P) recovers each walker's path (`per_walker`).
    log_prob: (n,) log-posterior of each sample. acceptance_rate: fraction of accepted proposals
    over the kept part only. settings: what produced it (step counts, proposal, seed-independent).
    """

    samples: np.ndarray
    log_prob: np.ndarray
    acceptance_rate: float
    names: tuple[str, ...]
    method: str
    settings: dict[str, Any] = field(default_factory=dict)
    n_walkers: int = 1

    @property
    def n_steps(self) -> int:
        """Kept iterations (per walker)."""
        return len(self.samples) // self.n_walkers

    def per_walker(self) -> np.ndarray:
        """(n_steps, n_walkers, P): the layout autocorrelation estimates need."""
        return self.samples.reshape(self.n_steps, self.n_walkers, len(self.names))

    def summary(self) -> str:
        """Human-readable: method, acceptance, and per parameter mean, std, MCSE, bulk and tail ESS, R-hat."""
        from ..diagnostics import chain_report  # diagnostics never imports samplers: no cycle

        head = (
            f"{self.method}: {self.n_steps} kept steps x {self.n_walkers} walker(s), "
            f"acceptance {self.acceptance_rate:.3f}"
        )
        table = chain_report([self])[["mean", "std", "mcse", "ess_bulk", "ess_tail", "rhat"]]
        return head + "\n" + table.to_string(float_format=lambda v: f"{v:.6g}")


@dataclass(frozen=True, eq=False)
class LaplaceResult:
    """Least-squares fit of the P-1 model parameters and the Laplace (Gaussian) approximation.

    theta_map (P-1,) SI; covariance (P-1, P-1) = s^2 (J^T J)^-1 with s^2 = SS / (k - (P-1)),
    SS the sum of squared residuals over k residual components; cost = SS / 2 (scipy's
    convention, kept for comparison with scipy's output); jacobian_singular_values of J with
    columns in step units (J * scale), largest first.

    Noise (k components i.i.d. N(0, sigma^2)): sigma_map = sqrt(SS / k), the maximum-likelihood
    value. Under the paper's posterior sigma^-(k+2) exp(-SS / 2 sigma^2) with the model linearised
    at theta_map (flat prior on theta integrated out), sigma^2 ~ SS / chi^2_nu, nu = k - (P-1) + 1,
    so exactly
        sigma_mean = sqrt(SS / 2) Gamma((nu - 1) / 2) / Gamma(nu / 2)
        sigma_std  = sqrt(SS / (nu - 2) - sigma_mean^2)   (~ sigma / sqrt(2 nu) ~ sigma / sqrt(2k)).
    sigma_mean / sigma_std are what an MCMC run of the paper's posterior should reproduce.
    """

    theta_map: np.ndarray
    covariance: np.ndarray
    sigma_map: float
    sigma_mean: float
    sigma_std: float
    cost: float
    jacobian_singular_values: np.ndarray
    n_residuals: int
    names: tuple[str, ...]

    @property
    def std(self) -> np.ndarray:
        """(P-1,) Laplace standard deviations of the model parameters, SI."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def theta_start(self) -> np.ndarray:
        """(P,) model parameters and sigma_map: a start for the samplers."""
        return np.append(self.theta_map, self.sigma_map)

    def full_covariance(self) -> np.ndarray:
        """(P, P) covariance including sigma (independent of theta at the linearisation point)."""
        p = len(self.theta_map)
        out = np.zeros((p + 1, p + 1))
        out[:p, :p] = self.covariance
        out[p, p] = self.sigma_std**2
        return out

    def moments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(mean, std, mcse), each (P,), for `diagnostics.cross_check`. mcse is 0: no Monte Carlo."""
        mean = np.append(self.theta_map, self.sigma_mean)
        std = np.append(self.std, self.sigma_std)
        return mean, std, np.zeros_like(mean)


# --------------------------------------------------------------------------------------------
# The random-walk Metropolis core, shared by the paper's and the adaptive sampler


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


# --------------------------------------------------------------------------------------------
# Samplers


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


class StudentT:
    """A multivariate Student-t proposal t_dof(mean (P,), inflation^2 covariance (P, P)): heavier
    tails than a Gaussian posterior's, so importance weights against it stay bounded."""

    def __init__(self, mean, covariance, dof: float, inflation: float):
        self.mean = np.asarray(mean, dtype=float)
        self.covariance = inflation**2 * np.asarray(covariance, dtype=float)
        self.dof, self.inflation = float(dof), float(inflation)
        self._factor = np.linalg.cholesky(self.covariance)
        self._inverse = np.linalg.inv(self._factor)
        p = len(self.mean)
        self._log_norm = (
            math.lgamma((self.dof + p) / 2)
            - math.lgamma(self.dof / 2)
            - 0.5 * p * math.log(self.dof * math.pi)
            - float(np.sum(np.log(np.diag(self._factor))))
        )

    def draw(self, rng: np.random.Generator, m: int) -> np.ndarray:
        """m draws (m, P)."""
        chi = rng.chisquare(self.dof, m) / self.dof
        return self.mean + (rng.standard_normal((m, len(self.mean))) @ self._factor.T) / np.sqrt(chi)[:, None]

    def log_density(self, x) -> np.ndarray:
        """Normalised log-density at x (m, P) -> (m,)."""
        z = (np.asarray(x, dtype=float) - self.mean) @ self._inverse.T
        return self._log_norm - 0.5 * (self.dof + len(self.mean)) * np.log1p(np.sum(z * z, axis=-1) / self.dof)


# A posterior can leave its Laplace approximation along a few directions only (a weakly determined
# combination that the data constrain at second order: its valley curves into the other directions,
# and its profile is not a parabola). Along those, `RidgeProposal` follows the valley.
BENT_NATS = 0.5  # a direction is bent when its profile departs from the Gaussian by more at 1 or 2 sd
RIDGE_SPAN = 30.0  # nats: the ridge is tabulated where its profile is within this of its peak
RIDGE_REACH = 8.0  # sd: the farthest the ridge is looked for along a bent direction
RIDGE_KNOTS = 41  # where the valley's floor is found (it is interpolated between them)
RIDGE_CELLS = 400  # the bent coordinate's density is tabulated on this many cells
NEWTON_STEPS = 3  # to the valley's floor, with the Laplace approximation's Hessian
GRADIENT_STEP = 1e-3  # of a whitened unit, for the central differences of the floor's Newton steps
DEFENSIVE_SHARE = 0.1  # proposals drawn from the Student-t: the weights stay bounded off the ridge


class RidgeProposal:
    """An independence proposal that follows the valleys along which a posterior leaves its
    Laplace approximation N(mean, covariance), mixed with a Student-t (`DEFENSIVE_SHARE`).

    In the approximation's whitened eigen-coordinates u (theta = mean + basis u), a direction k is
    bent when the log-posterior along it departs from the Gaussian by more than BENT_NATS at 1 or
    2 sd. Each bent coordinate t_k has its own tabulated density, the log-posterior along the
    valley's floor (piecewise constant on RIDGE_CELLS cells), and the other coordinates are Gaussian
    about the floor: u_straight = v + sum_k floor_k(t_k), v a Student-t like the fallback's (the
    same degrees of freedom and inflation: integrating sigma out leaves a t with about 3n degrees
    of freedom, heavier-tailed than a Gaussian). The map (t, v) -> u is a shear, so the density
    is the product of the parts; draws and densities are exact.
    `fit` returns None when no direction is bent: the Student-t alone is the proposal then.
    """

    def __init__(self, mean, basis, bent, knots, floors, edges, log_mass, fallback: StudentT):
        self.mean, self.basis = mean, basis
        self._inverse = np.linalg.inv(basis)
        self._log_det = float(np.linalg.slogdet(basis)[1])
        p = len(mean)
        self.bent = np.asarray(bent, dtype=int)
        self.straight = np.setdiff1d(np.arange(p), self.bent)
        self.knots, self.floors = knots, floors  # (B, K), (B, K, P - B)
        self.edges, self.log_mass = edges, log_mass  # (B, C + 1), (B, C) normalised
        self.fallback = fallback

    @classmethod
    def fit(cls, target: Target, mean, covariance, dof: float, inflation: float) -> RidgeProposal | None:
        """The proposal for `target` about its Laplace approximation (mean (P,), covariance (P, P)),
        or None when no direction is bent. About (4 + 2 P NEWTON_STEPS) RIDGE_KNOTS evaluations
        per bent direction."""
        mean = np.asarray(mean, dtype=float)
        values, vectors = np.linalg.eigh(np.asarray(covariance, dtype=float))
        basis = vectors * np.sqrt(values)
        p = len(mean)

        def log_p(u):
            return np.asarray(target.log_prob_many(mean + np.atleast_2d(u) @ basis.T), dtype=float)

        peak = float(log_p(np.zeros(p))[0])
        sds = np.array([-2.0, -1.0, 1.0, 2.0])
        along = (sds[None, :, None] * np.eye(p)[:, None, :]).reshape(-1, p)
        with np.errstate(invalid="ignore"):
            departure = (log_p(along) - peak).reshape(p, len(sds)) + 0.5 * sds**2
        bent = np.flatnonzero(~(np.abs(departure) <= BENT_NATS).all(axis=1))
        if len(bent) == 0 or len(bent) == p:
            return None
        straight = np.setdiff1d(np.arange(p), bent)
        parts = [cls._valley(log_p, peak, k, straight, p) for k in bent]
        knots, floors, edges, log_mass = (np.array([part[i] for part in parts]) for i in range(4))
        return cls(mean, basis, bent, knots, floors, edges, log_mass, StudentT(mean, covariance, dof, inflation))

    @staticmethod
    def _floors(log_p, k: int, straight: np.ndarray, p: int, knots: np.ndarray) -> np.ndarray:
        """The valley's floor (K, P - B) in the straight coordinates at bent coordinate k's knots
        (K,), found outwards from 0 (the mode), each knot's Newton steps from its inner neighbour's."""
        floors = np.zeros((len(knots), len(straight)))
        offsets = GRADIENT_STEP * np.concatenate([np.eye(len(straight)), -np.eye(len(straight))])
        centre = int(np.argmin(np.abs(knots)))
        order = [*range(centre, len(knots)), *range(centre - 1, -1, -1)]
        for i in order:
            inner = i - 1 if i > centre else min(i + 1, len(knots) - 1)
            u = np.zeros(p)
            u[k] = knots[i]
            u[straight] = floors[inner] if i != centre else 0.0
            for _ in range(NEWTON_STEPS):
                trial = np.repeat(u[None], len(offsets), axis=0)
                trial[:, straight] += offsets
                values = log_p(trial)
                gradient = (values[: len(straight)] - values[len(straight) :]) / (2 * GRADIENT_STEP)
                if not np.all(np.isfinite(gradient)):
                    break  # outside the support: keep the floor found so far
                u[straight] += gradient  # Newton's step: the whitened Hessian is -I
            floors[i] = u[straight]
        return floors

    @classmethod
    def _valley(cls, log_p, peak: float, k: int, straight: np.ndarray, p: int):
        """Bent coordinate k: its knots (K,), the floor (K, P - B) of the straight coordinates
        there, and its density's cells: edges (C + 1,) and normalised log-masses (C,). The range is
        where the log-posterior along the floor is within RIDGE_SPAN of the peak (at most
        RIDGE_REACH sd): found on coarse knots, then the floor again on knots across it."""

        def along_floor(knots, floors, at):
            path = np.zeros((len(at), p))
            path[:, k] = at
            path[:, straight] = np.column_stack([np.interp(at, knots, f) for f in floors.T])
            return log_p(path)

        coarse = np.linspace(-RIDGE_REACH, RIDGE_REACH, RIDGE_KNOTS)
        profile = along_floor(coarse, cls._floors(log_p, k, straight, p, coarse), coarse)
        near = np.flatnonzero(profile - peak > -RIDGE_SPAN)
        low = coarse[max(near[0] - 1, 0)] if len(near) else -1.0
        high = coarse[min(near[-1] + 1, len(coarse) - 1)] if len(near) else 1.0
        knots = np.linspace(low, high, RIDGE_KNOTS)
        floors = cls._floors(log_p, k, straight, p, knots)
        edges = np.linspace(low, high, RIDGE_CELLS + 1)
        profile = along_floor(knots, floors, 0.5 * (edges[1:] + edges[:-1]))
        profile = np.where(np.isfinite(profile), profile, -np.inf) + math.log(edges[1] - edges[0])
        return knots, floors, edges, profile - np.logaddexp.reduce(profile)

    def _floor(self, t: np.ndarray) -> np.ndarray:
        """sum_k floor_k(t_k): (m, P - B) for bent coordinates t (m, B)."""
        out = np.zeros((len(t), len(self.straight)))
        for b in range(len(self.bent)):
            out += np.column_stack([np.interp(t[:, b], self.knots[b], f) for f in self.floors[b].T])
        return out

    def _ridge_draw(self, rng: np.random.Generator, m: int) -> np.ndarray:
        u = np.empty((m, len(self.mean)))
        t = np.empty((m, len(self.bent)))
        for b in range(len(self.bent)):
            cumulative = np.cumsum(np.exp(self.log_mass[b]))
            cell = np.minimum(np.searchsorted(cumulative, rng.random(m) * cumulative[-1]), len(cumulative) - 1)
            width = self.edges[b, 1] - self.edges[b, 0]
            t[:, b] = self.edges[b, cell] + width * rng.random(m)
        u[:, self.bent] = t
        d, dof, inflation = len(self.straight), self.fallback.dof, self.fallback.inflation
        v = inflation * rng.standard_normal((m, d)) / np.sqrt(rng.chisquare(dof, m) / dof)[:, None]
        u[:, self.straight] = v + self._floor(t)
        return self.mean + u @ self.basis.T

    def draw(self, rng: np.random.Generator, m: int) -> np.ndarray:
        """m draws (m, P): each from the ridge or, with probability DEFENSIVE_SHARE, the Student-t."""
        ridge, student = self._ridge_draw(rng, m), self.fallback.draw(rng, m)
        return np.where((rng.random(m) < DEFENSIVE_SHARE)[:, None], student, ridge)

    def _ridge_log_density(self, x: np.ndarray) -> np.ndarray:
        u = (x - self.mean) @ self._inverse.T
        t = u[:, self.bent]
        d, dof, inflation = len(self.straight), self.fallback.dof, self.fallback.inflation
        v = (u[:, self.straight] - self._floor(t)) / inflation
        out = (
            math.lgamma((dof + d) / 2)
            - math.lgamma(dof / 2)
            - 0.5 * d * math.log(dof * math.pi)
            - d * math.log(inflation)
            - 0.5 * (dof + d) * np.log1p(np.sum(v * v, axis=1) / dof)
            - self._log_det
        )
        for b in range(len(self.bent)):
            width = self.edges[b, 1] - self.edges[b, 0]
            cell = np.floor((t[:, b] - self.edges[b, 0]) / width).astype(int)
            inside = (cell >= 0) & (cell < self.log_mass.shape[1])
            out = out + np.where(inside, self.log_mass[b, np.clip(cell, 0, self.log_mass.shape[1] - 1)], -np.inf)
            out = out - math.log(width)
        return out

    def log_density(self, x) -> np.ndarray:
        """Normalised log-density of the mixture at x (m, P) -> (m,)."""
        x = np.asarray(x, dtype=float)
        return np.logaddexp(
            math.log1p(-DEFENSIVE_SHARE) + self._ridge_log_density(x),
            math.log(DEFENSIVE_SHARE) + self.fallback.log_density(x),
        )

    def report(self, names: Sequence[str]) -> list[list[tuple[str, float]]]:
        """Per bent direction, its four main parts (parameter name, weight in the unit eigenvector),
        largest first (a list: a JSON object's keys are written sorted)."""
        out = []
        for k in self.bent:
            direction = self.basis[:, k] / np.linalg.norm(self.basis[:, k])
            main = np.argsort(-np.abs(direction), kind="stable")[:4]
            out.append([(names[i], round(float(direction[i]), 3)) for i in main])
        return out


def metropolis_independence(
    target: Target,
    rng: np.random.Generator,
    start,
    mean,
    covariance,
    n_samples: int = 20_000,
    burn_in: int = 2_000,
    dof: float = 10.0,
    inflation: float = 1.2,
    batch: int = BLOCK,
    proposal: StudentT | RidgeProposal | None = None,
) -> Chain:
    """Independence Metropolis-Hastings with a multivariate Student-t proposal t_dof(mean,
    inflation^2 covariance), e.g. from a Laplace approximation, or another `proposal` (e.g. a
    `RidgeProposal` about the same approximation).

    For a posterior close to its Laplace approximation (a near-linear model under Gaussian
    priors) nearly every proposal is accepted and successive states are nearly independent, so
    the effective sample size is close to the number of steps, where a random walk in P
    dimensions needs about 3 P steps per effective sample. The t's tails are heavier than a
    Gaussian posterior's, so the importance weights stay bounded and the chain is uniformly
    ergodic. Proposals do not depend on the state: they are drawn and evaluated a batch at a
    time (`log_prob_many`), and the loop only accepts or rejects, with the ratio
    p(x') q(x) / (p(x) q(x')). start (P,) SI; n_samples total steps including burn_in.
    """
    p = len(target.names)
    if proposal is None:
        proposal = StudentT(mean, covariance, dof, inflation)
    kept = _check_counts(n_samples, burn_in)
    walker = _start(target, start)
    theta, lp, lq = walker.theta, walker.log_prob, float(proposal.log_density(walker.theta[None])[0])
    samples, log_probs = np.empty((kept, p)), np.empty(kept)
    accepted = 0
    for begin in range(0, n_samples, batch):
        m = min(batch, n_samples - begin)
        proposals = proposal.draw(rng, m)
        lp_new = np.asarray(target.log_prob_many(proposals), dtype=float)
        if np.isnan(lp_new).any():
            raise SamplingError(f"log_prob returned NaN at theta = {proposals[np.isnan(lp_new)][0].tolist()}")
        lq_new = proposal.log_density(proposals)
        with np.errstate(divide="ignore"):
            log_u = np.log(rng.random(m))
        for i in range(m):
            step = begin + i
            if log_u[i] < (lp_new[i] - lp) - (lq_new[i] - lq):
                theta, lp, lq = proposals[i], float(lp_new[i]), float(lq_new[i])
                if step >= burn_in:
                    accepted += 1
            if step >= burn_in:
                samples[step - burn_in] = theta
                log_probs[step - burn_in] = lp
    settings = {
        "n_samples": n_samples,
        "burn_in": burn_in,
        "dof": dof,
        "inflation": inflation,
        "proposal": type(proposal).__name__,
        "proposal_covariance": inflation**2 * np.asarray(covariance, dtype=float),
    }
    return Chain(samples, log_probs, accepted / kept, tuple(target.names), "metropolis_independence", settings)


def run_emcee(
    target: Target,
    rng: np.random.Generator,
    start,
    spread,
    n_walkers: int = 32,
    n_steps: int = 5_000,
    burn_in: int = 1_000,
    enough: Callable[[np.ndarray], bool] | None = None,
    max_doublings: int = 0,
) -> Chain:
    """emcee's affine-invariant ensemble (stretch move), log_prob_many over all walkers per call.

    start (P,) SI; spread (P,) or scalar SI: walkers start at start + spread * N(0, 1), redrawn
    where the log-posterior is -inf (e.g. sigma <= 0). n_steps total per walker including
    burn_in. emcee's own generator is a RandomState seeded from `rng`, so runs are reproducible
    and the global NumPy state is neither used nor changed.

    enough: a test of the kept walkers' paths (n_steps, n_walkers, P), e.g. the convergence
    criteria; while it fails, the same ensemble runs on for as many kept steps again (the run
    doubles), at most max_doublings times. So a run is as long as its criteria need, not longer.
    """
    import emcee

    p = len(target.names)
    if n_walkers < 2 * p:
        raise ValueError(f"emcee needs at least 2P = {2 * p} walkers, got {n_walkers}")
    kept = _check_counts(n_steps, burn_in)
    centre = _start(target, start).theta
    spread = np.broadcast_to(np.asarray(spread, dtype=float), (p,))
    walkers = centre + spread * rng.standard_normal((n_walkers, p))
    for _ in range(100):
        bad = ~np.isfinite(target.log_prob_many(walkers))
        if not bad.any():
            break
        walkers[bad] = centre + spread * rng.standard_normal((int(bad.sum()), p))
    else:
        raise SamplingError(
            f"{int(bad.sum())} of {n_walkers} initial walkers stay outside the support after 100 redraws: reduce spread"
        )
    seed = int(rng.integers(2**32))
    initial = emcee.State(walkers, random_state=np.random.RandomState(seed).get_state())
    sampler = emcee.EnsembleSampler(n_walkers, p, target.log_prob_many, vectorize=True)
    state = sampler.run_mcmc(initial, burn_in, progress=False) if burn_in else initial
    accepted_before = sampler.backend.accepted.copy() if burn_in else np.zeros(n_walkers)
    # the state is emcee's own after burn-in: its walker-independence check is for user starts,
    # and would reject an ensemble still contracting towards a far posterior
    state = sampler.run_mcmc(state, kept, progress=False, skip_initial_state_check=bool(burn_in))
    doublings = 0
    while enough is not None and doublings < max_doublings and not enough(sampler.get_chain(discard=burn_in)):
        state = sampler.run_mcmc(state, kept * 2**doublings, progress=False)
        doublings += 1
    kept *= 2**doublings
    accepted = sampler.backend.accepted - accepted_before
    settings = {
        "n_steps": burn_in + kept,
        "burn_in": burn_in,
        "n_walkers": n_walkers,
        "spread": spread.copy(),
        "doublings": doublings,
    }
    return Chain(
        sampler.get_chain(discard=burn_in, flat=True),
        sampler.get_log_prob(discard=burn_in, flat=True),
        float(accepted.sum() / (kept * n_walkers)),
        tuple(target.names),
        "emcee",
        settings,
        n_walkers=n_walkers,
    )


def extend(
    target: Target,
    rng: np.random.Generator,
    chain: Chain,
    n_steps: int,
    progress: Callable[[int, int, float], None] | None = None,
) -> Chain:
    """`chain` (a random-walk Metropolis chain: the adaptive or the paper's) run on for n_steps
    more steps from its last state with its own proposal, frozen since its burn-in, so the longer
    chain is the same time-homogeneous Markov chain, only longer. settings["n_samples"] counts
    the steps added, settings["doublings"] how many times it was extended."""
    if "proposal_covariance" in chain.settings and chain.method == "metropolis_adaptive":
        draw = _gaussian_steps(np.asarray(chain.settings["proposal_covariance"], dtype=float))
    elif "proposal_half_widths" in chain.settings:
        draw = _uniform_steps(np.asarray(chain.settings["proposal_half_widths"], dtype=float))
    else:
        raise ValueError(f"a {chain.method} chain cannot be extended: only random-walk Metropolis chains can")
    if n_steps < 1:
        raise ValueError(f"n_steps must be at least 1, got {n_steps}")
    walker = _Walker(chain.samples[-1].copy(), float(chain.log_prob[-1]))
    samples, log_probs, accepted = _walk(target, rng, walker, n_steps, draw, True, _Progress(progress, n_steps))
    kept = chain.n_steps
    accepted_before = round(chain.acceptance_rate * kept)  # the rate is a count over kept steps
    settings = {
        **chain.settings,
        "n_samples": chain.settings.get("n_samples", kept) + n_steps,
        "doublings": chain.settings.get("doublings", 0) + 1,
    }
    return Chain(
        np.concatenate([chain.samples, samples]),
        np.concatenate([chain.log_prob, log_probs]),
        (accepted_before + accepted) / (kept + n_steps),
        chain.names,
        chain.method,
        settings,
    )


def run_chains(
    sampler_fn: Callable[..., Chain],
    target: Target,
    rng: np.random.Generator,
    n_chains: int,
    starts,
    *,
    enough: Callable[[list[Chain]], bool] | None = None,
    max_doublings: int = 0,
    **kw,
) -> list[Chain]:
    """n_chains >= 2 independent runs of sampler_fn(target, child_rng, start, **kw).

    starts: (n_chains, P) one start each (overdispersed starts make R-hat meaningful) or (P,)
    shared. Child generators come from rng.spawn, so chain i is the same whatever n_chains.

    enough: a test of the chains together (R-hat needs them all), e.g. the convergence criteria;
    while it fails, every chain runs on (`extend`, its own generator) for as many kept steps
    again, so the kept part doubles, at most max_doublings times (as `run_emcee` does).
    """
    if n_chains < 2:
        raise ValueError(f"run_chains needs n_chains >= 2 for between-chain diagnostics, got {n_chains}")
    starts = np.asarray(starts, dtype=float)
    if starts.ndim == 1:
        starts = np.broadcast_to(starts, (n_chains, len(starts)))
    if len(starts) != n_chains:
        raise ValueError(f"starts has {len(starts)} rows for {n_chains} chains")
    children = rng.spawn(n_chains)
    chains = [sampler_fn(target, child, start, **kw) for child, start in zip(children, starts)]
    doublings = 0
    while enough is not None and doublings < max_doublings and not enough(chains):
        chains = [extend(target, child, c, c.n_steps, kw.get("progress")) for child, c in zip(children, chains)]
        doublings += 1
    return chains


# --------------------------------------------------------------------------------------------
# Least squares and the Laplace approximation


def _undetermined(vt: np.ndarray, small: np.ndarray, names: Sequence[str]) -> list[dict[str, float]]:
    """For each null direction (row of V^T in step units), its parameters with weight >= 0.1."""
    out = []
    for row in vt[small]:
        row = row / row[np.argmax(np.abs(row))]
        out.append({names[i]: float(row[i]) for i in np.flatnonzero(np.abs(row) >= 0.1)})
    return out


def least_squares_mode(
    residuals: Callable[[np.ndarray], np.ndarray],
    theta0,
    scale,
    jacobian="2-point",
    method: str = "trf",
    starts=(),
):
    """The minimum of the sum of squared residuals(theta) (k,) over theta (P,) SI: scipy's least
    squares from theta0 (P,) to tolerances of 1e-12, scale (P,) SI step units as its x_scale;
    jacobian: a callable theta -> (k, P), or scipy's "2-point" forward differences; method: scipy's
    "trf" or "lm" (MINPACK: no SVD of the whole Jacobian per step). starts (m, P): further starts,
    the best of all kept. Returns scipy's OptimizeResult (x, cost = SS / 2, jac at x). The mode of
    both Laplace approximations: the paper fit's (`least_squares_laplace`) and the block models'
    under their priors (`evidence.posterior_mode`)."""
    import scipy.optimize

    fits = [
        scipy.optimize.least_squares(
            residuals, x, jac=jacobian, x_scale=scale, method=method, xtol=1e-12, ftol=1e-12, gtol=1e-12
        )
        for x in [theta0, *starts]
    ]
    return min(fits, key=lambda f: f.cost)


def least_squares_laplace(
    residuals: Callable[[np.ndarray], np.ndarray],
    theta0,
    scale,
    rng=None,
    names: Sequence[str] | None = None,
    jacobian=None,
    n_restarts: int = 0,
    restart_spread: float = 1.0,
    rcond: float = RCOND,
) -> LaplaceResult:
    """Minimise the sum of squared residuals(theta) (k,) over theta (P-1,) SI; Laplace covariance.

    scale (P-1,) SI step units: used as scipy's x_scale and to make singular values unit-free.
    jacobian: optional callable theta -> (k, P-1); finite differences otherwise. n_restarts > 0
    also starts from theta0 + restart_spread * scale * N(0, 1) (needs rng) and keeps the best.

    Raises NotIdentifiable naming the parameter combinations whose singular value of J * scale is
    below rcond * the largest: their variance would be (near) infinite, and a pseudo-inverse would
    silently report a finite one. See `LaplaceResult` for the sigma formulas.

    Not `evidence.laplace_at`, which approximates another posterior for another use: this one is the
    paper's (flat prior on theta, sigma^-(k+2), any residual function), with sigma integrated out:
    covariance s^2 (J^T J)^-1 at s^2 = SS / (k - (P-1)), sigma's exact marginal mean and std, the
    SVD test above, no evidence: the start and scale of the paper's samplers. `laplace_at` takes a
    block model's joint mode in (theta, log sigma) under its priors and noise shape, inverts the
    (P + 1)-square Hessian there (sigma^2 at SS / (k + 1), sigma correlated with theta) and gives
    the log evidence the loop compares models by. On the paper's model at the same mode, this
    theta covariance is that one's times (k + 1) / (k - P + 1).
    """
    from scipy.special import gammaln

    theta0 = np.asarray(theta0, dtype=float)
    scale = np.broadcast_to(np.asarray(scale, dtype=float), theta0.shape)
    names = tuple(names) if names is not None else tuple(f"theta[{i}]" for i in range(len(theta0)))
    starts = []
    if n_restarts:
        if rng is None:
            raise ValueError("n_restarts > 0 needs rng")
        starts = list(theta0 + restart_spread * scale * rng.standard_normal((n_restarts, len(theta0))))
    fit = least_squares_mode(residuals, theta0, scale, "2-point" if jacobian is None else jacobian, "trf", starts)
    r = np.asarray(residuals(fit.x), dtype=float).ravel()
    k, m = r.size, len(theta0)
    sum_squares = float(r @ r)  # scipy's fit.cost is HALF of this
    if k <= m + 2:
        raise ValueError(f"{k} residuals cannot determine {m} parameters and sigma (need k > P + 1)")
    j = np.asarray(jacobian(fit.x) if jacobian is not None else fit.jac, dtype=float).reshape(k, m)
    # SVD of J in step units: a unit-free conditioning test; cov = D (J_s^T J_s)^-1 D s^2.
    singular, vt, small = undetermined_directions(j, scale, rcond)
    if small.any():
        combos = _undetermined(vt, small, names)
        text = "; ".join(" + ".join(f"{w:+.3g}*{n}" for n, w in c.items()) for c in combos)
        raise NotIdentifiable(
            f"the data do not determine {int(small.sum())} parameter combination(s) (singular values of "
            f"J in step units {singular[small]} < {rcond:g} x {singular[0]:.3g}): {text}. "
            f"Fix one parameter of each combination or add data that separates them.",
            combos,
        )
    s2 = sum_squares / (k - m)
    inverse = (vt.T / singular**2) @ vt
    covariance = s2 * inverse * np.outer(scale, scale)
    nu = k - m + 1
    sigma_mean = math.sqrt(sum_squares / 2) * math.exp(gammaln((nu - 1) / 2) - gammaln(nu / 2))
    sigma_std = math.sqrt(max(sum_squares / (nu - 2) - sigma_mean**2, 0.0))
    return LaplaceResult(
        theta_map=fit.x.copy(),
        covariance=covariance,
        sigma_map=math.sqrt(sum_squares / k),
        sigma_mean=sigma_mean,
        sigma_std=sigma_std,
        cost=float(fit.cost),
        jacobian_singular_values=singular,
        n_residuals=k,
        names=names,
    )
