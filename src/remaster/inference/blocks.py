"""The measurement model as parameter blocks (`BlockModel`): the paper's zero-offsets and
registration, plus optional blocks for the effects the paper's model leaves out (docs/methods.md,
"Parameter blocks"; the parameters of each block: `parameter_blocks`).

    angles_i = q_i + dtheta + c tau_i + c' tau_payload,i + s_q q_i + r t_i
               + sum_k (a_k cos k q_i + b_k sin k q_i)                               (joint space)
    p_N,i    = (I + D)(1 + s_N) T*(Theta1) T_NR FK_links(angles_i) (marker + delta)  (sensor frame)

Joint-space blocks are linear in their parameters: each parameter k adds theta_k * v_k,i to one
joint's angle, with v_k (n,) fixed per dataset (ones, gravity torques, readings, elapsed time:
`readings`). Gravity torques come once per dataset from Pinocchio (`remaster.robot.gravity`), with
a tool-plate payload m0 that is a setting. A true payload m differs from it by a torque of a
different shape than the arm's own, which c alone cannot follow (1.5 kg off leaves several um on a
laser tracker); c' on the payload's part of the torque absorbs it exactly: c'_j = c_j (m / m0 - 1).
Link geometry is complete: each fixed transform F_j of the chain (and the tool's) gets a small rigid
motion of its own frame, six parameters (`kinematics.perturbed_transforms`), the local form of the
product-of-exponentials model (Okamura & Park 1996; Chen, Yang & Lin 2001). It is continuous (no
singularity at parallel axes, unlike DH; no Hayati parameter needed) and complete (any error of a
fixed transform is one); it is made minimal by the identification Jacobian (`extensions`).

A `BlockModel` shows the samplers, the Laplace fit and the metrics only names, a parameter
vector, a predict function and the paper's log-posterior. The paper's model is a `BlockModel`
without extension blocks (`paper_model`). Which extension parameters a model carries is decided
by `extensions.extended_model`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from .. import _kernels
from ..noise import RangeTransverse
from ..robot.gravity import without_mass
from ..robot.kinematics import LINK_MOTION, KernelForm, KinematicChain, perturbed_transforms
from ..robot.priors import Priors
from .model import correction_transforms
from .parameter_blocks import BASE, EXTENSIONS, Parameters, block_parameters, distortion_matrix, link_labels
from .readings import Readings

# the paper's sum of squares is expanded in the zero-offsets (`BlockModel._expansion`) from this many
# rows per term of the expansion (3^N): below, summing over the rows is as fast (7 joints: about 40 us
# each way at 500 rows); above, the expansion's cost stays and the rows' grows (benchmarks/bench_expansion.py:
# 37 us against 11 us at 1,000 rows, 4.0 ms against 15 us at 100,000)
EXPANDED_ROWS_PER_TERM = 0.25


class BlockModel:
    """Predicted marker positions (sensor frame) of one set's readings for base + extension blocks.

    chain: the nominal chain; data: `Readings`; marker (3,) m nominal, flange frame; t_nr (4, 4)
    the initial registration; blocks: extension block names (any order; the model orders them
    as EXTENSIONS); fixed: {parameter name: value} held (e.g. the zero-offset a free
    registration absorbs, the extension parameters the data cannot see); noise: the sensor's noise
    shape (`remaster.noise`), None for the paper's isotropic noise: the likelihood then sums the
    squares of whitened residuals (`weighted_residuals`), while `residuals` stay in metres.
    Parameters: `names` (P,) free ones, `scale` (P,) their display units in SI, `unit` (P,).
    Everything that does not depend on the parameters (sines and cosines of the readings, the
    chain's fixed transforms) is computed once.
    """

    def __init__(
        self,
        chain: KinematicChain,
        data: Readings,
        marker,
        t_nr,
        blocks: Sequence[str] = (),
        fixed: Mapping[str, float] | None = None,
        priors: Priors | None = None,
        noise: RangeTransverse | None = None,
    ):
        unknown = set(blocks) - set(EXTENSIONS)
        if unknown:
            raise ValueError(f"unknown extension blocks {sorted(unknown)}; use some of {EXTENSIONS}")
        if "drift" in blocks and data.drift is None:
            raise ValueError("a drift block needs a time or temperature column")
        if "joint_compliance" in blocks and (
            data.torques is None or data.payload_torques is None or (without_mass(chain) and data.body_torques is None)
        ):
            raise ValueError("a joint_compliance block needs the readings' gravity torques (`readings`)")
        self.chain, self.data = chain, data
        self.q, self.measured = data.q, data.measured
        self.marker = np.asarray(marker, dtype=float)
        self.t_nr = np.asarray(t_nr, dtype=float)
        self.blocks = BASE + tuple(b for b in EXTENSIONS if b in blocks)
        parts = [block_parameters(b, chain, data.drift_unit, data.harmonic_orders) for b in self.blocks]
        self.all_names = tuple(n for p in parts for n in p.names)
        self.all_scale = np.concatenate([p.scale for p in parts])
        self.all_unit = tuple(u for p in parts for u in p.unit)
        self.block_of = {n: b for b, p in zip(self.blocks, parts) for n in p.names}
        fixed = dict(fixed or {})
        unknown = set(fixed) - set(self.all_names)
        if unknown:
            raise ValueError(f"cannot hold parameters {sorted(unknown)} the model does not have")
        self.fixed = fixed
        self.free = np.array([n not in fixed for n in self.all_names])
        self.fixed_values = np.array([fixed.get(n, 0.0) for n in self.all_names])
        self._free_index = np.flatnonzero(self.free)
        self.names = tuple(n for n, f in zip(self.all_names, self.free) if f)
        self.scale = self.all_scale[self.free]
        self.unit = tuple(u for u, f in zip(self.all_unit, self.free) if f)
        self._setup_joint_space(parts)
        index = {n: i for i, n in enumerate(self.all_names)}
        self._marker_index = [index[n] for n in self.all_names if self.block_of[n] == "marker_offset"]
        self._scale_index = [index[n] for n in self.all_names if self.block_of[n] == "sensor_scale"]
        self._distortion_index = [index[n] for n in self.all_names if self.block_of[n] == "sensor_distortion"]
        self._links = (
            [(index[name], row, column) for row, column, name in link_labels(chain)]
            if "link_geometry" in self.blocks
            else []
        )
        self._kernel = KernelForm.of(chain)
        self.priors = priors
        # (P,) SI prior std of the free parameters: inf for the paper's (flat), finite for the extensions'
        self.prior_std = np.array(
            [
                math.inf if priors is None or self.block_of[n] in BASE else priors.std_of(n, data.drift_unit)
                for n in self.names
            ]
        )
        self._prior_precision = np.where(np.isfinite(self.prior_std), 1.0 / self.prior_std**2, 0.0)
        # the sensor's noise shape (`remaster.noise`): None is the paper's isotropic noise
        self.noise = noise
        self._whitening = None if noise is None else noise.whitening(self.measured)
        self.noise_log_det = 0.0 if noise is None else noise.log_det_term(self.measured)
        if data.weights is not None:  # per-point stds: S_i = sigma^2 V_i S_i' V_i, V_i = diag(weights_i)
            scaling = 1.0 / np.asarray(data.weights, dtype=float)
            shape = np.eye(3) if self._whitening is None else self._whitening
            self._whitening = scaling[:, :, None] * np.broadcast_to(shape, (len(scaling), 3, 3))
            self.noise_log_det += float(np.sum(np.log(scaling)))
        self._has_prior = bool(np.any(self._prior_precision))
        self._setup_orientation(data)
        self._setup_compiled()

    def _setup_compiled(self) -> None:
        """The paper's model (no extension block, isotropic noise: `paper_model`, a full-pose probe's
        orientations included) has its sum of squares and its random walk compiled: the samplers
        evaluate it hundreds of thousands of times. Its arrays in the kernels' form."""
        self.compiled_posterior = len(self.blocks) == len(BASE) and self._whitening is None
        self._expanded = None
        if not self.compiled_posterior:
            return
        self._start = self._kernel.start(self.marker)
        self._measured_t = np.ascontiguousarray(self.measured.T)
        if not self.has_orientation:
            self._orientation_kernel = (
                np.eye(3),
                *2 * [np.zeros((0, self.chain.n_joints))],
                np.zeros((0, 3, 3)),
                np.zeros(1),
            )
            return
        q = self.q[self._orientation_at]
        self._orientation_kernel = (
            self._orientation_tail,
            np.ascontiguousarray(np.cos(q)),
            np.ascontiguousarray(np.sin(q)),
            self._measured_rotations,
            np.array([float(self.data.orientation_weight)]),
        )

    def _setup_joint_space(self, parts: Sequence[Parameters]) -> None:
        """values (K, n) and joints (K,) of the joint-space parameters: angle_j += theta_k values_k."""
        index = {n: i for i, n in enumerate(self.all_names)}
        rows = [(index[n], j, key) for p in parts for n, j, key in zip(p.names, p.joints, p.regressor)]
        self._joint_params = np.array([i for i, _, _ in rows], dtype=int)
        self._joint_values_t = np.array([self.data.regressor(key)[:, j] for _, j, key in rows]).T.copy()  # (n, K)
        self._joint_onehot = np.eye(self.chain.n_joints)[[j for _, j, _ in rows]]  # (K, N)
        # the compiled kernel's form (`_kernels.points_linear`): the zero-offsets as offsets, the
        # parameters whose regressor varies by reading grouped by joint, joint j's at first[j] .. first[j + 1] - 1
        constant = np.array([key == "ones" for _, _, key in rows], dtype=bool)
        joints = np.array([j for _, j, _ in rows], dtype=int)
        order = np.flatnonzero(~constant)[np.argsort(joints[~constant], kind="stable")]
        self._offset_params, self._offset_onehot = self._joint_params[constant], self._joint_onehot[constant]
        self._kernel_params = self._joint_params[order]
        self._kernel_values = np.ascontiguousarray(self._joint_values_t[:, order].T)  # (K, n)
        self._kernel_first = np.searchsorted(joints[order], np.arange(self.chain.n_joints + 1))
        self._cos_q, self._sin_q = np.ascontiguousarray(np.cos(self.q.T)), np.ascontiguousarray(np.sin(self.q.T))

    def _setup_orientation(self, data: Readings) -> None:
        """The rows whose probe orientation was measured and their rotations (`orientation_residuals`)."""
        self.has_orientation = data.orientations is not None
        if not self.has_orientation:
            self._orientation_at = np.empty(0, dtype=int)
            return
        if {"link_geometry", "sensor_distortion"} & set(self.blocks):
            raise ValueError("a probe's orientation is modelled with the joint-space blocks only")
        measured = np.asarray(data.orientations, dtype=float)
        self._orientation_at = np.flatnonzero(np.all(np.isfinite(measured), axis=(1, 2)))
        self._measured_rotations = np.ascontiguousarray(measured[self._orientation_at])
        # what follows the last joint's z-aligned frame of the kernel form: the flange, then the probe
        tool = self._kernel.bases[-1].T @ self.chain.tool_transform[:3, :3]
        self._orientation_tail = np.ascontiguousarray(tool @ np.asarray(data.probe_rotation, dtype=float))

    @property
    def n_points(self) -> int:
        """Measured positions (rows)."""
        return len(self.q)

    @property
    def n_orientations(self) -> int:
        """Measured probe orientations (rows with one; 0 for points alone)."""
        return len(self._orientation_at)

    @property
    def n_rows(self) -> int:
        """Rows of three components the likelihood sums over: positions, then orientations."""
        return self.n_points + self.n_orientations

    @property
    def row_readings(self) -> np.ndarray:
        """(n_rows,) the reading (0..n-1) each row of `weighted_residuals` belongs to: every
        position's, then each measured orientation's."""
        return np.concatenate([np.arange(self.n_points), self._orientation_at])

    def orientation_residuals(self, theta) -> np.ndarray:
        """log(R_measured R_predicted^T) as rotation vectors (n_o, 3) or (m, n_o, 3), rad, sensor
        frame, from free parameters (P,) or (m, P): R_predicted = R_registration R_flange(angles)
        R_probe at the rows whose orientation was measured."""
        every = self.full(theta)
        stack = np.atleast_2d(every)
        out = _kernels.orientation_residuals(
            self._kernel.rotations,
            self._orientation_tail,
            np.ascontiguousarray((correction_transforms(stack[:, :6]) @ self.t_nr)[:, :3, :3]),
            np.ascontiguousarray(self.angles(stack)[:, self._orientation_at]),
            self._measured_rotations,
        )
        return out if every.ndim == 2 else out[0]

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
        """E = p_ref - p_predicted, (n, 3) or (m, n, 3), m."""
        return self.measured - self.predict(theta)

    def jacobian(self, theta, step: float = 1e-7) -> np.ndarray:
        """d residuals / d free parameters by central differences, (3n, P) (SI units)."""
        theta = np.asarray(theta, dtype=float)
        steps = step * np.eye(len(theta))
        both = self.residuals(np.concatenate([theta + steps, theta - steps]))
        plus, minus = both[: len(theta)], both[len(theta) :]
        return ((plus - minus) / (2 * step)).reshape(len(theta), -1).T

    def vector(self, values: Mapping[str, float]) -> np.ndarray:
        """Free-parameter vector (P,) from {name: value}; parameters not given are 0."""
        return np.array([float(values.get(n, 0.0)) for n in self.names])

    def values(self, theta) -> dict[str, float]:
        """{name: value} of every parameter (held ones included) from free parameters (P,)."""
        return dict(zip(self.all_names, self.full(theta).tolist()))

    def on(self, data: Readings) -> BlockModel:
        """The same model (blocks, registration, held parameters, priors) on other readings, e.g.
        the validation set."""
        return BlockModel(
            self.chain, data, self.marker, self.t_nr, self.blocks[len(BASE) :], self.fixed, self.priors, self.noise
        )

    def with_noise(self, noise: RangeTransverse | None) -> BlockModel:
        """The same model on the same readings with another noise shape."""
        return BlockModel(
            self.chain, self.data, self.marker, self.t_nr, self.blocks[len(BASE) :], self.fixed, self.priors, noise
        )

    def whitening_matrices(self) -> np.ndarray:
        """(n_points, 3, 3): each position's whitening W_i (`whitened` of unit residuals, column a = W_i e_a;
        the identity for isotropic noise)."""
        unit = np.broadcast_to(np.eye(3)[:, None, :], (3, self.n_points, 3))
        return np.moveaxis(self.whitened(unit), 0, -1)

    def whitened(self, residuals) -> np.ndarray:
        """Residuals (n, 3) or (m, n, 3) in units of the noise's range std: W_i e_i (`remaster.noise`);
        unchanged for isotropic noise."""
        if self._whitening is None:
            return np.asarray(residuals)
        return np.einsum("nij,...nj->...ni", self._whitening, residuals)

    def weighted_residuals(self, theta) -> np.ndarray:
        """Whitened residuals (n_rows, 3) or (m, n_rows, 3): what the likelihood sums the squares of;
        a full-pose probe's orientation residuals (`orientation_residuals`) times the readings'
        orientation_weight follow the n positions' rows."""
        positions = self.whitened(self.residuals(theta))
        if not self.has_orientation:
            return positions
        orientations = self.data.orientation_weight * self.orientation_residuals(theta)
        return np.concatenate([positions, orientations], axis=-2)

    def weighted_jacobian(self, theta, step: float) -> np.ndarray:
        """d whitened residuals / d free parameters, (3 n_rows, P)."""
        if self.has_orientation:
            theta = np.asarray(theta, dtype=float)
            steps = step * np.eye(len(theta))
            both = self.weighted_residuals(np.concatenate([theta + steps, theta - steps]))
            return ((both[: len(theta)] - both[len(theta) :]) / (2 * step)).reshape(len(theta), -1).T
        jacobian = self.jacobian(theta, step)
        if self._whitening is None:
            return jacobian
        return np.einsum("nij,njp->nip", self._whitening, jacobian.reshape(self.n_points, 3, -1)).reshape(
            jacobian.shape
        )

    def log_prior(self, theta) -> np.ndarray:
        """Log of the extension blocks' Gaussian priors, up to their normalisation: scalar or (m,)."""
        theta = np.asarray(theta, dtype=float)
        return -0.5 * np.sum(theta**2 * self._prior_precision, axis=-1)

    def log_posterior(self, theta, sigma):
        """The paper's: -(3n + 2) log sigma - E / (2 sigma^2) (flat prior on the registration and
        the zero-offsets, Jeffreys' on sigma), plus the extension blocks' priors (`log_prior`);
        -inf where sigma <= 0; n counts a probe's orientations with its positions (`n_rows`).
        Scalar or (m,)."""
        if np.ndim(sigma) == 0:  # one chain step: plain floats are several times cheaper
            sigma = float(sigma)
            if sigma <= 0.0:
                value = -math.inf
            else:
                value = -(3 * self.n_rows + 2) * math.log(sigma) - float(self.sum_squares(theta)) / (
                    2.0 * sigma * sigma
                )
        else:
            sigma = np.asarray(sigma, dtype=float)
            energy = self.sum_squares(theta)
            positive = sigma > 0
            safe = np.where(positive, sigma, 1.0)
            value = -(3 * self.n_rows + 2) * np.log(safe) - energy / (2.0 * safe**2)
            value = np.where(positive, value, -np.inf)
        return value + self.log_prior(theta) if self._has_prior else value

    def prior_residuals(self, theta) -> np.ndarray:
        """theta_k / std_k of the parameters with a prior (P_prior,) or (m, P_prior): least squares'
        pseudo-observations."""
        finite = np.isfinite(self.prior_std)
        return np.asarray(theta, dtype=float)[..., finite] / self.prior_std[finite]

    def angles(self, every) -> np.ndarray:
        """Joint angles (n, N) or (m, n, N) the robot had, from every parameter (..., P_all)."""
        theta = np.asarray(every, dtype=float)[..., self._joint_params]
        return self.q + self._joint_values_t @ (theta[..., :, None] * self._joint_onehot)

    def robot_points(self, every) -> np.ndarray:
        """Marker positions (n, 3) or (m, n, 3) in the ROBOT frame from every parameter (P_all,)
        or (m, P_all): what the calibrated robot is, without the sensor's set-up. A stack is
        evaluated a chunk of vectors at a time, each chunk by one compiled call."""
        every = np.asarray(every, dtype=float)
        stack = np.atleast_2d(every)
        chunk = max(1, min(self._CHUNK, self._ANGLES_PER_CALL // max(self.q.size, 1)))
        points = np.concatenate(
            [self._robot_points(stack[begin : begin + chunk]) for begin in range(0, len(stack), chunk)]
        )
        return points if every.ndim == 2 else points[0]

    # vectors per compiled call: at most _CHUNK, and at most _ANGLES_PER_CALL joint angles in all,
    # which bounds the (chunk, n, 3) points (and the transforms of a link-geometry stack) in memory
    # whatever the campaign's size; the angles themselves are taken inside the kernel
    _CHUNK = 512
    _ANGLES_PER_CALL = 2**22  # 32 MB per array

    def _robot_points(self, stack: np.ndarray) -> np.ndarray:
        """Marker positions (m, n, 3) in the robot frame for parameter vectors (m, P_all)."""
        kernel = self._kernel
        if self._links:
            errors = np.zeros((len(stack), self.chain.n_joints + 1, len(LINK_MOTION)))
            for index, row, column in self._links:
                errors[:, row, column] = stack[:, index]
            kernel = kernel.with_transforms(
                *perturbed_transforms(self.chain.joint_transforms, self.chain.tool_transform, errors)
            )
        marker = self.marker + stack[:, self._marker_index] if self._marker_index else self.marker
        rotations, shifts = kernel.rotations, kernel.shifts
        starts = np.atleast_2d(kernel.start(marker))
        return _kernels.points_linear(
            rotations.reshape((-1,) + rotations.shape[-3:]),
            shifts.reshape((-1,) + shifts.shape[-2:]),
            starts,
            self._cos_q,
            self._sin_q,
            stack[:, self._offset_params] @ self._offset_onehot,
            self._kernel_values,
            self._kernel_first,
            np.ascontiguousarray(stack[:, self._kernel_params]),
        )

    def predict_full(self, every) -> np.ndarray:
        """Predicted positions (n, 3) or (m, n, 3) in the sensor frame from every parameter
        (P_all,) or (m, P_all). A stack is a loop over its m vectors (not over rows)."""
        every = np.asarray(every, dtype=float)
        stack = np.atleast_2d(every)
        points = self.robot_points(stack)
        transform = correction_transforms(stack[:, :6]) @ self.t_nr
        out = points @ np.swapaxes(transform[:, :3, :3], -1, -2) + transform[:, None, :3, 3]
        if self._scale_index:
            out = out * (1.0 + stack[:, self._scale_index])[:, :, None]
        if self._distortion_index:  # (I + D) p about the sensor's origin
            out = out + out @ np.swapaxes(distortion_matrix(stack[:, self._distortion_index]), -1, -2)
        return out if every.ndim == 2 else out[0]

    def sensor_rotation(self, theta) -> np.ndarray:
        """(3, 3) rotation of the registration at free parameters theta (P,): robot -> sensor frame."""
        every = np.atleast_2d(self.full(theta))
        return (correction_transforms(every[:, :6]) @ self.t_nr)[0, :3, :3]

    def sum_squares(self, theta) -> np.ndarray:
        """Sum of squared (whitened) residuals E(theta): scalar or (m,). The paper's model's is
        compiled (`_kernels.registered_sum_squares`, the same predictions summed in a loop)."""
        if not self.compiled_posterior:
            return np.sum(self.weighted_residuals(theta) ** 2, axis=(-2, -1))
        every = self.full(theta)
        stack = every.reshape(-1, every.shape[-1])
        expansion = self._expansion()
        if expansion[0].shape[0] > 0:
            energy = _kernels.expanded_sum_squares(expansion, stack, self.t_nr)
        else:
            energy = _kernels.registered_sum_squares(
                self._kernel.rotations,
                self._kernel.shifts,
                self._start,
                self._cos_q,
                self._sin_q,
                stack,
                self.t_nr,
                self._measured_t,
            )
        if self.has_orientation:
            tail, cos_q, sin_q, measured, weight = self._orientation_kernel
            energy = energy + _kernels.orientation_sum_squares(
                self._kernel.rotations, tail, stack, self.t_nr, cos_q, sin_q, measured, weight[0]
            )
        return energy if every.ndim == 2 else energy[0]

    def _expansion(self) -> tuple:
        """The paper's sum of squares expanded in the zero-offsets (`_kernels.expansion_sums`, about
        `fixed_values`), made at the first call when the campaign has at least `EXPANDED_ROWS_PER_TERM`
        rows per term (3^N terms): an evaluation then costs the same at any number of rows. Below,
        arrays without terms (each evaluation sums over the rows)."""
        if self._expanded is None:
            if self.n_points >= EXPANDED_ROWS_PER_TERM * 3**self.chain.n_joints:
                sums = _kernels.expansion_sums(
                    self._kernel.rotations,
                    self._kernel.shifts,
                    self._start,
                    self._cos_q,
                    self._sin_q,
                    self.fixed_values,
                    self.t_nr,
                    self._measured_t,
                )
            else:
                sums = (np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(5))
            self._expanded = (*sums, np.ascontiguousarray(self.fixed_values, dtype=float))
        return self._expanded

    def metropolis_block(self, theta, log_prob: float, steps, log_u):
        """Random-walk Metropolis steps on the paper's model's `log_posterior` over (free
        parameters, sigma), compiled (`_kernels.metropolis_walk`): from theta (P + 1,) with its
        log_prob, proposals theta + steps[i] (m, P + 1) accepted when log_u[i] (m,) < the log-ratio.
        Returns (states (m, P + 1), their log-posteriors (m,), accepted count, index of the first
        NaN log-posterior or -1). Only for a model with `compiled_posterior`."""
        if not self.compiled_posterior:
            raise ValueError("only the paper's model (no extension block, isotropic noise) has a compiled walk")
        steps = np.ascontiguousarray(steps, dtype=float)
        states, log_probs = np.empty_like(steps), np.empty(len(steps))
        accepted, nan_at = _kernels.metropolis_walk(
            self._kernel.rotations,
            self._kernel.shifts,
            self._start,
            self._cos_q,
            self._sin_q,
            self.t_nr,
            self._measured_t,
            self._expansion(),
            self._orientation_kernel,
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


def paper_model(
    chain: KinematicChain, q, measured, marker, t_nr, fixed=None, table_rows=None, orientation: Mapping | None = None
) -> BlockModel:
    """The paper's model (eqs. point_mod_transf and posterior, `remaster.inference.model`): the
    registration and zero-offsets alone, flat priors, isotropic noise, for one sensor's measured
    points. q (n, N) rad; measured (n, 3) m in the sensor frame, all finite (unseen points are
    excluded by the caller, who counts them); marker (3,) m, flange frame; t_nr (4, 4) the initial
    registration; fixed: {parameter name: value} held; table_rows (n,): the sensor table's row of
    each point (default 0..n-1), the model's `data.rows`; orientation: a full-pose probe's
    `orientation_fields` at those rows (its orientations enter the likelihood beside the points)."""
    q = np.asarray(q, dtype=float)
    measured = np.asarray(measured, dtype=float)
    if measured.shape != (len(q), 3) or not np.all(np.isfinite(measured)):
        raise ValueError("measured must be finite with shape (n, 3) matching q")
    rows = np.arange(len(q)) if table_rows is None else np.asarray(table_rows, dtype=int)
    return BlockModel(chain, Readings(rows, q, measured, **(orientation or {})), marker, t_nr, (), fixed)
