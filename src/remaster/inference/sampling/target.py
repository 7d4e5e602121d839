"""What the samplers take and give, against a generic posterior: nothing here knows about robots.

A `Target` is P named parameters (the last one, by convention, "noise.sigma" > 0), a log-posterior
that is -inf outside the support, and `scale` (P,): the SI size of each parameter's natural step
unit (1 mm = 1e-3 for lengths, 1 deg = pi/180 for angles). `CallableTarget` makes one of plain
functions. Every sampler returns a `Chain`, and raises `SamplingError` when it cannot start or
continue.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ...errors import RemasterError


class SamplingError(RemasterError, ValueError):
    """A sampler cannot start or continue: a start outside the support, a NaN log-posterior."""


# --------------------------------------------------------------------------------------------
# The target interface


@runtime_checkable
class Target(Protocol):
    """What the samplers need of a posterior (e.g. `posterior_targets.PosteriorTarget`); nothing about robots.

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
        from ...diagnostics import chain_report  # diagnostics never imports the samplers: no cycle

        head = (
            f"{self.method}: {self.n_steps} kept steps x {self.n_walkers} walker(s), "
            f"acceptance {self.acceptance_rate:.3f}"
        )
        table = chain_report([self])[["mean", "std", "mcse", "ess_bulk", "ess_tail", "rhat"]]
        return head + "\n" + table.to_string(float_format=lambda v: f"{v:.6g}")
