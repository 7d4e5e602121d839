"""The posterior of a block model as the samplers take it (`sampling.target.Target`): over its free
parameters and sigma (`PosteriorTarget`, the paper's), or with sigma integrated out and drawn back
exactly for each sample (`SigmaMarginalTarget`, the loop closure's refit); evaluated a stack of
parameter vectors at a time.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .blocks import BlockModel
from .model import SIGMA, display_scale
from .sampling.target import Chain

POINTS_PER_CALL = 2**20  # predicted points held at once by a stacked evaluation (24 MB per array)


@dataclass(frozen=True)
class PosteriorTarget:
    """The log-posterior of a model over (free parameters..., noise.sigma), for the samplers."""

    model: BlockModel

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.names + (SIGMA,)

    @property
    def scale(self) -> np.ndarray:
        """Step units: the model's own (extended models have their own units), sigma in mm."""
        return np.append(self.model.scale, display_scale(SIGMA))

    def log_prob(self, theta) -> float:
        theta = np.asarray(theta, dtype=float)
        return float(self.model.log_posterior(theta[:-1], theta[-1]))

    @property
    def walk_block(self):
        """The model's compiled random-walk block (`BlockModel.metropolis_block`) when it has one
        (the paper's model), else None: the samplers then step in Python."""
        return self.model.metropolis_block if self.model.compiled_posterior else None

    def log_prob_many(self, thetas) -> np.ndarray:
        """Log-posterior (m,) of m vectors (m, P + 1), a slice of at most POINTS_PER_CALL / n
        vectors at a time: each vector's predictions (n, 3) are held at once, so a sampler's
        batch of thousands of proposals stays within memory on a campaign of any size."""
        thetas = np.asarray(thetas, dtype=float)
        size = max(1, POINTS_PER_CALL // max(self.model.n_points, 1))
        return np.concatenate(
            [
                self.model.log_posterior(part[:, :-1], part[:, -1])
                for part in (thetas[k : k + size] for k in range(0, len(thetas), size))
            ]
            or [np.empty(0)]
        )

    def residuals(self, theta_model) -> np.ndarray:
        """Residual vector (3n,) of the model parameters (sigma excluded), for least squares; a
        full-pose probe's weighted orientation residuals follow (`BlockModel.weighted_residuals`)."""
        if self.model.has_orientation:
            return self.model.weighted_residuals(theta_model).ravel()
        return self.model.residuals(theta_model).ravel()


@dataclass(frozen=True)
class SigmaMarginalTarget:
    """The posterior of a model's free parameters with sigma integrated out, for the samplers.

    Under Jeffreys' prior the log-posterior is -(N + 2) log sigma - SS(theta) / (2 sigma^2) + log
    prior(theta), N = 3n, so sigma integrates out in closed form: log p(theta) = -(N + 1) / 2
    log SS(theta) + log prior(theta), and given theta, SS / sigma^2 is chi-square with N + 1 degrees
    of freedom. Sampling theta alone removes the coupling of sigma with theta's scale (the joint
    mode's sigma is sqrt(N / (N + 1)) times its marginal's, with theta's spread in proportion),
    which a Laplace approximation about the joint mode misses; `with_sigma` then draws sigma exactly."""

    model: BlockModel

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.names

    @property
    def scale(self) -> np.ndarray:
        return self.model.scale

    def log_prob(self, theta) -> float:
        return float(self.log_prob_many(np.asarray(theta, dtype=float)[None, :])[0])

    def log_prob_many(self, thetas) -> np.ndarray:
        """Log marginal posterior (m,) of m vectors (m, P), up to a constant, a slice at a time
        (`PosteriorTarget.log_prob_many`)."""
        thetas = np.asarray(thetas, dtype=float)
        size = max(1, POINTS_PER_CALL // max(self.model.n_points, 1))
        power = 0.5 * (3 * self.model.n_rows + 1)
        parts = []
        for k in range(0, len(thetas), size):
            part = thetas[k : k + size]
            with np.errstate(divide="ignore"):
                value = -power * np.log(self.model.sum_squares(part))
            parts.append(value + self.model.log_prior(part))
        return np.concatenate(parts) if parts else np.empty(0)

    def with_sigma(self, chain: Chain, rng: np.random.Generator) -> Chain:
        """`chain` over theta (the model's own parameters) with sigma drawn from p(sigma | theta) for
        each sample, appended as the last parameter, and the joint log-posterior as log_prob."""
        theta = chain.samples
        energy = self.model.sum_squares(theta)
        sigma = np.sqrt(energy / rng.chisquare(3 * self.model.n_rows + 1, len(theta)))
        return replace(
            chain,
            samples=np.column_stack([theta, sigma]),
            log_prob=self.model.log_posterior(theta, sigma),
            names=self.names + (SIGMA,),
        )
