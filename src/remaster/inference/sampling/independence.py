"""Independence Metropolis-Hastings (`metropolis_independence`): proposals drawn whatever the state,
from a Laplace approximation, for posteriors close to it (the loop closure's extended models).

The proposals: `StudentT`, a multivariate Student-t about the approximation, and `RidgeProposal`,
which follows the valleys along which a posterior leaves it. Step counts: `n_samples` is the
total number of iterations INCLUDING burn-in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .random_walk import BLOCK, _check_counts, _start
from .target import Chain, SamplingError, Target


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
