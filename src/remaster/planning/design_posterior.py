"""The linearized posterior of the complete error model at configurations not yet measured: what a
set of measurements would let the calibration predict (docs/planning.md).

The complete error model is the loop closure's (`remaster.inference.blocks`): registration,
zero-offsets, link geometry (every fixed transform's small rigid motion, made minimal by
`extensions.structural_redundancy`) and the marker offset, under the priors of config.yaml
(`remaster.robot.priors`). Linearized at zero corrections, with the sensor's isotropic noise sigma
(m), the posterior covariance of the parameters after measuring configurations q_1..q_n is

    Sigma = (J^T J / sigma^2 + P^-1)^-1,    J = d p_sensor / d theta at q_1..q_n (3n, P),

P the prior covariance: the extension blocks' priors; the paper's flat priors of the registration and
zero-offsets become a vague Gaussian of VAGUE_STD display units (mm, deg), wide enough to say nothing
(the calibration's accuracy is thousands of times finer) and proper, so that the design starts from
a finite covariance. Parameters no configuration can separate (joint 1's zero-offset against the
registration's rotation; the link motions absorbed at every configuration) are held, as the fit
holds them. Parameters are in display units (theta / scale): the information matrix of mm, deg and
tracker noise is then well conditioned.

The predicted position at a configuration q has the covariance C(q) = J_q Sigma J_q^T (3, 3) m^2,
and its 95 % bound is the 95th percentile of |p - p_mean| under N(0, C), the quantity `remaster
predict` reports from posterior draws (bound95_mm): `inference.bounds.bound_from_covariances`, which
needs only the trace and the Frobenius norm of C, what a design's thousands of candidates x
evaluation points can afford.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..inference import identifiability
from ..inference.blocks import BlockModel
from ..inference.extensions import spread_configurations, structural_redundancy
from ..inference.readings import Readings
from ..robot.kinematics import KinematicChain
from ..robot.priors import Priors

COMPLETE_BLOCKS = ("marker_offset", "link_geometry")
# std (display units: mm, deg) standing in for the flat prior of the registration and zero-offsets
VAGUE_STD = 100.0
# configurations per Jacobian evaluation: bounds the (2P, n, 3) stacked predictions in memory
JACOBIAN_CHUNK = 4096
STEP = identifiability.JACOBIAN_STEP


def probe_readings(q) -> Readings:
    """Readings at configurations q (n, N) rad with nothing measured (zeros) and no torques: what a
    Jacobian of the geometric blocks needs."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    zeros = np.zeros_like(q)
    return Readings(np.arange(len(q)), q, np.zeros((len(q), 3)), zeros, zeros)


@dataclass(frozen=True, eq=False)
class ErrorModel:
    """The complete error model's linearization, ready for design.

    chain, marker (3,) m flange frame, t_nr (4, 4) robot -> sensor; blocks: extension blocks;
    held: {parameter: value} held (base combinations no configuration separates, structurally
    absorbed link motions); names (P,) free parameters; scale (P,) SI size of their display unit;
    prior_precision (P,) in display units^-2; sigma (m) the sensor's noise per axis."""

    chain: KinematicChain
    marker: np.ndarray
    t_nr: np.ndarray
    blocks: tuple[str, ...]
    held: Mapping[str, float]
    names: tuple[str, ...]
    scale: np.ndarray
    prior_precision: np.ndarray
    sigma: float

    def model(self, q) -> BlockModel:
        """The block model at configurations q (n, N) rad, held parameters held."""
        return BlockModel(self.chain, probe_readings(q), self.marker, self.t_nr, self.blocks, self.held)

    def jacobian(self, q) -> np.ndarray:
        """d p_sensor / d parameters (n, 3, P) at configurations q (n, N) rad, m per display unit,
        by central differences at zero corrections."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        parts = []
        for begin in range(0, len(q), JACOBIAN_CHUNK):
            model = self.model(q[begin : begin + JACOBIAN_CHUNK])
            # d residual = -d prediction: the sign does not matter to a covariance, but keep the prediction's
            parts.append(-model.jacobian(np.zeros(len(self.names)), STEP).reshape(-1, 3, len(self.names)))
        jacobian = np.concatenate(parts) if parts else np.zeros((0, 3, len(self.names)))
        return jacobian * self.scale

    def whitened_jacobian(self, q) -> np.ndarray:
        """`jacobian` over the noise sigma (n, 3, P): a measurement's information is J^T J of it."""
        return self.jacobian(q) / self.sigma

    def prior_information(self) -> np.ndarray:
        """P^-1 (P, P), display units^-2."""
        return np.diag(self.prior_precision)


def complete_error_model(
    chain: KinematicChain,
    marker,
    t_nr,
    priors: Priors,
    sigma: float,
    blocks: Sequence[str] = COMPLETE_BLOCKS,
    held: Mapping[str, float] | None = None,
) -> ErrorModel:
    """The complete error model of `chain` measured at `marker` (3,) m by a sensor at `t_nr` (4, 4)
    with noise `sigma` (m per axis), under `priors`. Held: what the identifiability analysis of the
    zero-offset model holds at configurations spread over the joint limits (joint 1 against the
    registration), the link motions absorbed at every configuration, and `held` (the campaign's own,
    when given)."""
    if not sigma > 0:
        raise ValueError(f"the sensor's noise must be > 0 m, got {sigma!r}")
    marker = np.asarray(marker, dtype=float)
    t_nr = np.asarray(t_nr, dtype=float)
    spread = spread_configurations(chain)
    if held is None:
        held = dict(identifiability.analyse(BlockModel(chain, probe_readings(spread), marker, t_nr)).held)
    held = dict(held)
    structural = structural_redundancy(BlockModel(chain, probe_readings(spread), marker, t_nr, blocks, held))
    held.update({name: 0.0 for name in structural})
    model = BlockModel(chain, probe_readings(spread[:1]), marker, t_nr, blocks, held, priors)
    prior_std = np.where(np.isfinite(model.prior_std), model.prior_std / model.scale, VAGUE_STD)
    return ErrorModel(
        chain, marker, t_nr, tuple(model.blocks[2:]), held, model.names, model.scale, 1.0 / prior_std**2, float(sigma)
    )


def information(whitened_jacobian) -> np.ndarray:
    """J^T J (P, P) of whitened Jacobians (n, 3, P)."""
    j = np.asarray(whitened_jacobian, dtype=float).reshape(-1, np.shape(whitened_jacobian)[-1])
    return j.T @ j


def covariance(information_matrix) -> np.ndarray:
    """Sigma = information^-1 (P, P) by Cholesky, symmetric."""
    import scipy.linalg

    factor = scipy.linalg.cho_factor(information_matrix)
    inverse = scipy.linalg.cho_solve(factor, np.eye(len(information_matrix)))
    return 0.5 * (inverse + inverse.T)


def position_covariances(eval_jacobian, sigma_matrix) -> np.ndarray:
    """C(q) = J_q Sigma J_q^T (E, 3, 3) m^2 of Jacobians (E, 3, P) m per display unit."""
    j = np.asarray(eval_jacobian, dtype=float)
    return np.einsum("eip,pq,ejq->eij", j, sigma_matrix, j, optimize=True)


def woodbury_update(sigma_matrix, whitened_jacobian) -> np.ndarray:
    """Sigma after one more measurement with whitened Jacobian (3, P) (or several, (k, 3, P)):
    Sigma - Sigma J^T (I + J Sigma J^T)^-1 J Sigma, the rank-3 (3k) Sherman-Morrison-Woodbury step."""
    j = np.asarray(whitened_jacobian, dtype=float).reshape(-1, len(sigma_matrix))
    b = sigma_matrix @ j.T
    s = np.eye(len(j)) + j @ b
    updated = sigma_matrix - b @ np.linalg.solve(s, b.T)
    return 0.5 * (updated + updated.T)
