"""The paper's measurement model and its posterior (eqs. point_mod_transf and posterior).

    p_N,i = T*(Theta1) T_NR FK(q_i + Theta2) marker,   E_i = p_ref,i - p_N,i ~ N(0, sigma^2 I3)

Theta1 = registration.{x, y, z, alpha, beta, gamma} corrects the initial sensor <- robot
transform T_NR: T* = Trans(x, y, z) Rz(alpha) Ry(beta) Rx(gamma). Theta2 = zero_offsets.q1..qN
add to the joint readings. With a flat prior on Theta and Jeffreys' on sigma the log-posterior is

    log p(Theta, sigma | data) = -(3n + 2) log sigma - E(Theta) / (2 sigma^2) + const,

E the sum of squared residuals over the n measured points. Parameters are SI (m, rad);
`scale` gives the paper's display units (mm, deg) in SI, which samplers use as step units.

Some parameters may be held at fixed values (an explicit mask), e.g. the zero-offset that a free
registration absorbs exactly (see `remaster.inference.identifiability`). Everything that does not depend
on the parameters (sines and cosines of the readings, T_NR) is computed once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from .. import _kernels, spatial
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..units import DEG, MM

REGISTRATION = ("x", "y", "z", "alpha", "beta", "gamma")
SIGMA = "noise.sigma"


def parameter_names(n_joints: int) -> tuple[str, ...]:
    """Every model parameter (sigma excluded), registration first."""
    return tuple(f"registration.{p}" for p in REGISTRATION) + tuple(f"zero_offsets.q{j + 1}" for j in range(n_joints))


def display_scale(name: str) -> float:
    """SI size of one display unit of a parameter: 1 mm for lengths, 1 deg for angles."""
    return MM if name in ("registration.x", "registration.y", "registration.z", SIGMA) else DEG


def display_value(name: str, value: float) -> float:
    """A parameter value in its display unit (mm or deg)."""
    return float(value) / display_scale(name)


def display_unit(name: str) -> str:
    """'mm' or 'deg': the display unit of a parameter (`display_scale`)."""
    return "mm" if display_scale(name) == MM else "deg"


def by_parameter(table):
    """A parameter table (a `parameter` column, or already indexed by it) indexed by parameter name."""
    return table.set_index("parameter") if "parameter" in table.columns else table


def correction_transforms(registration) -> np.ndarray:
    """T*(Theta1) (..., 4, 4) for registration parameters (..., 6): Trans(x,y,z) Rz Ry Rx."""
    r = np.asarray(registration, dtype=float)
    rotation = spatial.euler_zyx_to_matrix(r[..., 3], r[..., 4], r[..., 5])
    return spatial.homogeneous(rotation, r[..., :3])


def correction_parameters(transform) -> np.ndarray:
    """The inverse of `correction_transforms`: (..., 6) (x, y, z m; alpha, beta, gamma rad) of
    transforms (..., 4, 4)."""
    t = np.asarray(transform, dtype=float)
    return np.concatenate([t[..., :3, 3], spatial.matrix_to_euler_zyx(t[..., :3, :3])], axis=-1)


class MeasurementModel:
    """What every measurement model shares (`remaster.inference.blocks` adds parameter blocks to the
    paper's): parameters held or free, predictions from the free ones, residuals, their Jacobian
    and the paper's log-posterior. A subclass sets q (n, N), measured (n, 3), fixed_values
    (P_all,) and _free_index, and gives `predict_full` and `sum_squares`."""

    @property
    def n_points(self) -> int:
        return len(self.q)

    def full(self, theta) -> np.ndarray:
        """Free parameters (..., P) -> every parameter (..., P_all), held ones at their values."""
        theta = np.asarray(theta, dtype=float)
        out = np.empty(theta.shape[:-1] + self.fixed_values.shape)
        out[...] = self.fixed_values
        out[..., self._free_index] = theta
        return out

    def predict(self, theta) -> np.ndarray:
        """Predicted positions (n, 3) or (m, n, 3) from free parameters (P,) or (m, P)."""
        return self.predict_full(self.full(theta))

    def residuals(self, theta) -> np.ndarray:
        """E = p_ref - p_predicted, (n, 3) or (m, n, 3)."""
        return self.measured - self.predict(theta)

    def log_posterior(self, theta, sigma) -> np.ndarray:
        """The paper's: -(3n + 2) log sigma - E / (2 sigma^2) (flat prior on Theta, Jeffreys' on
        sigma); -inf where sigma <= 0. Scalar or (m,)."""
        if np.ndim(sigma) == 0:  # one chain step: plain floats are several times cheaper
            sigma = float(sigma)
            if sigma <= 0.0:
                return -math.inf
            return -(3 * self.n_points + 2) * math.log(sigma) - float(self.sum_squares(theta)) / (2.0 * sigma * sigma)
        sigma = np.asarray(sigma, dtype=float)
        energy = self.sum_squares(theta)
        positive = sigma > 0
        safe = np.where(positive, sigma, 1.0)
        value = -(3 * self.n_points + 2) * np.log(safe) - energy / (2.0 * safe**2)
        return np.where(positive, value, -np.inf)

    def jacobian(self, theta, step: float = 1e-7) -> np.ndarray:
        """d residuals / d free parameters by central differences, (3n, P) (SI units)."""
        theta = np.asarray(theta, dtype=float)
        steps = step * np.eye(len(theta))
        both = self.residuals(np.concatenate([theta + steps, theta - steps]))
        plus, minus = both[: len(theta)], both[len(theta) :]
        return ((plus - minus) / (2 * step)).reshape(len(theta), -1).T


class ZeroOffsetModel(MeasurementModel):
    """Predicted marker positions in the sensor frame and the log-posterior, for one sensor's
    measured points.

    q: joint readings (n, N) rad; measured: marker positions (n, 3) m in the sensor frame (all
    finite: unseen points are excluded by the caller, who counts them); marker (3,) m in the
    flange frame; t_nr (4, 4) the initial registration; fixed: {parameter name: value} held;
    table_rows (n,): which row of the sensor's table each point is (default 0..n-1).
    """

    def __init__(
        self,
        chain: KinematicChain,
        q,
        measured,
        marker,
        t_nr,
        fixed: Mapping[str, float] | None = None,
        table_rows=None,
    ):
        self.chain = chain
        self.q = np.asarray(q, dtype=float)
        self.table_rows = np.arange(len(self.q)) if table_rows is None else np.asarray(table_rows, dtype=int)
        self.measured = np.asarray(measured, dtype=float)
        if self.measured.shape != (len(self.q), 3) or not np.all(np.isfinite(self.measured)):
            raise ValueError("measured must be finite with shape (n, 3) matching q")
        self.marker = np.asarray(marker, dtype=float)
        self.t_nr = np.asarray(t_nr, dtype=float)
        self.all_names = parameter_names(chain.n_joints)
        fixed = dict(fixed or {})
        unknown = set(fixed) - set(self.all_names)
        if unknown:
            raise ValueError(f"cannot hold unknown parameters {sorted(unknown)}")
        self.free = np.array([name not in fixed for name in self.all_names])
        self.fixed_values = np.array([fixed.get(name, 0.0) for name in self.all_names])
        self.names = tuple(n for n, f in zip(self.all_names, self.free) if f)
        self.scale = np.array([display_scale(n) for n in self.names])
        self._fk = ForwardKinematics(chain, self.q)
        self._start = self._fk.flange_point(self.marker)
        self._measured_t = np.ascontiguousarray(self.measured.T)
        self._free_index = np.flatnonzero(self.free)

    def predict_full(self, every) -> np.ndarray:
        """Predicted positions (n, 3) or (m, n, 3) in the sensor frame from every parameter (..., 6 + N)."""
        every = np.asarray(every, dtype=float)
        points = self._fk.points(self.marker, every[..., 6:])
        transform = correction_transforms(every[..., :6]) @ self.t_nr
        rotation_t = np.swapaxes(transform[..., :3, :3], -1, -2)
        return points @ rotation_t + transform[..., None, :3, 3]

    def sum_squares(self, theta) -> np.ndarray:
        """E(Theta) of eq. cost_function: scalar or (m,). Compiled: this is the hot path."""
        every = self.full(theta)
        fk = self._fk
        energy = _kernels.registered_sum_squares(
            fk.kernel_rotations,
            fk.kernel_shifts,
            self._start,
            fk.kernel_cos_q,
            fk.kernel_sin_q,
            every.reshape(-1, every.shape[-1]),
            self.t_nr,
            self._measured_t,
        )
        return energy if every.ndim == 2 else energy[0]

    def metropolis_block(self, theta, log_prob: float, steps, log_u):
        """Random-walk Metropolis steps on `log_posterior` over (free parameters, sigma), compiled
        (`_kernels.metropolis_walk`): from theta (P + 1,) with its log_prob, proposals theta + steps[i]
        (m, P + 1) accepted when log_u[i] (m,) < the log-ratio. Returns (states (m, P + 1), their
        log-posteriors (m,), accepted count, index of the first NaN log-posterior or -1)."""
        fk = self._fk
        steps = np.ascontiguousarray(steps, dtype=float)
        states, log_probs = np.empty_like(steps), np.empty(len(steps))
        accepted, nan_at = _kernels.metropolis_walk(
            fk.kernel_rotations,
            fk.kernel_shifts,
            self._start,
            fk.kernel_cos_q,
            fk.kernel_sin_q,
            self.t_nr,
            self._measured_t,
            self.fixed_values,
            self._free_index,
            np.asarray(theta, dtype=float),
            float(log_prob),
            steps,
            np.asarray(log_u, dtype=float),
            states,
            log_probs,
        )
        return states, log_probs, int(accepted), int(nan_at)
