"""Compiled (Numba) kernels for the hot path: marker positions and sums of squared residuals.

A sampler evaluates the posterior one parameter vector at a time hundreds of thousands of
times; in NumPy each evaluation costs tens of array operations of Python overhead (about
50 us for 173 configurations), compiled it costs a few microseconds. The NumPy implementation
in `remaster.robot.kinematics` stays the reference the tests compare these kernels against.

The kernels take the chain with every joint axis turned onto its frame's z axis (see
`ForwardKinematics`): joint j maps a point x of its frame to rotations[j] Rz(angle) x + shifts[j],
and cos and sin of q + offset come from the angle-sum formulas.
"""

from __future__ import annotations

import functools

import numpy as np

_KERNELS: list = []  # (function, njit options) in definition order: callees before callers


def _compiled(**options):
    """numba.njit(cache=True, **options), compiled at the first call of any kernel: importing
    numba costs a few tenths of a second, which every workflow job that only reads results (tables,
    figures) would otherwise pay."""

    def mark(function):
        _KERNELS.append((function, options))

        @functools.wraps(function)
        def first_call(*args):
            _compile_all()
            return globals()[function.__name__](*args)

        return first_call

    return mark


def _compile_all() -> None:
    """Replace every kernel by its Numba dispatcher (callees first, so callers compile against them)."""
    import numba

    for function, options in _KERNELS:
        if not isinstance(globals()[function.__name__], numba.core.registry.CPUDispatcher):
            globals()[function.__name__] = numba.njit(cache=True, **options)(function)


@_compiled(fastmath={"contract"}, inline="always")
def _through_joint(r, shift, c, s, x0, x1, x2, i):
    """Point i of x0, x1, x2 through one joint: Rz by the angle whose cosine and sine are c and s,
    then the joint's fixed rotation r (3, 3) and shift (3,)."""
    r0 = c * x0[i] - s * x1[i]
    r1 = s * x0[i] + c * x1[i]
    z = x2[i]
    x0[i] = r[0, 0] * r0 + r[0, 1] * r1 + r[0, 2] * z + shift[0]
    x1[i] = r[1, 0] * r0 + r[1, 1] * r1 + r[1, 2] * z + shift[1]
    x2[i] = r[2, 0] * r0 + r[2, 1] * r1 + r[2, 2] * z + shift[2]


@_compiled(fastmath={"contract"})
def _points(rotations, shifts, start, cos_q, sin_q, cos_d, sin_d, x0, x1, x2):
    """Positions of `start` (a point in the last joint's frame) for every configuration, into
    x0, x1, x2 (n,). cos_q, sin_q are (N, n): joints outer, configurations inner, so that the
    inner loop runs over independent configurations and vectorises."""
    x0[:] = start[0]
    x1[:] = start[1]
    x2[:] = start[2]
    for j in range(rotations.shape[0] - 1, -1, -1):
        cd, sd = cos_d[j], sin_d[j]
        r = rotations[j]
        for i in range(x0.shape[0]):
            c = cos_q[j, i] * cd - sin_q[j, i] * sd
            s = sin_q[j, i] * cd + cos_q[j, i] * sd
            _through_joint(r, shifts[j], c, s, x0, x1, x2, i)


@_compiled()
def points(rotations, shifts, start, cos_q, sin_q, cos_d, sin_d):
    """Positions (m, n, 3) for m offset vectors given by cos_d, sin_d (m, N)."""
    m, n = cos_d.shape[0], cos_q.shape[1]
    out = np.empty((m, n, 3))
    x0, x1, x2 = np.empty(n), np.empty(n), np.empty(n)
    for k in range(m):
        _points(rotations, shifts, start, cos_q, sin_q, cos_d[k], sin_d[k], x0, x1, x2)
        out[k, :, 0] = x0
        out[k, :, 1] = x1
        out[k, :, 2] = x2
    return out


SMALL_ANGLE = 0.02  # rad: below it, cos and sin by their Taylor series to the 8th order, exact in double precision


@_compiled(fastmath={"contract"})
def _points_linear(rotations, shifts, start, cos_q, sin_q, offsets, values, first, coefficients, x0, x1, x2):
    """`_points` at joint angles q[i, j] + offsets[j] + d[i, j] with d linear in parameters:
    d[i, j] = sum over k in first[j] .. first[j + 1] - 1 of coefficients[k] values[k, i] (a
    compliance times a torque, a gear-ratio error times an angle, a drift times a time). cos_q,
    sin_q (N, n) of the readings, offsets (N,), values (K, n) with joint j's rows at first[j] ..
    first[j + 1] - 1, coefficients (K,). The angle-sum formulas take cos and sin of q + offset
    from those of q, and d, a few milliradians, turns them by its Taylor series: no sine or
    cosine is evaluated per configuration, which would cost ten times the rest."""
    x0[:] = start[0]
    x1[:] = start[1]
    x2[:] = start[2]
    for j in range(rotations.shape[0] - 1, -1, -1):
        cd, sd = np.cos(offsets[j]), np.sin(offsets[j])
        r = rotations[j]
        for i in range(x0.shape[0]):
            c = cos_q[j, i] * cd - sin_q[j, i] * sd
            s = sin_q[j, i] * cd + cos_q[j, i] * sd
            d = 0.0
            for k in range(first[j], first[j + 1]):
                d += coefficients[k] * values[k, i]
            if d != 0.0:
                if abs(d) < SMALL_ANGLE:
                    d2 = d * d
                    cos_d = 1.0 - 0.5 * d2 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0))
                    sin_d = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0)))
                else:
                    cos_d, sin_d = np.cos(d), np.sin(d)
                c, s = c * cos_d - s * sin_d, s * cos_d + c * sin_d
            _through_joint(r, shifts[j], c, s, x0, x1, x2, i)


@_compiled()
def points_linear(rotations, shifts, starts, cos_q, sin_q, offsets, values, first, coefficients):
    """Positions (m, n, 3) for m parameter vectors whose joint angles are linear in them
    (`_points_linear`): rotations (m, N, 3, 3), shifts (m, N, 3), starts (m, 3) (a leading
    dimension of 1 is shared by every vector), offsets (m, N), coefficients (m, K)."""
    m, n = coefficients.shape[0], cos_q.shape[1]
    out = np.empty((m, n, 3))
    x0, x1, x2 = np.empty(n), np.empty(n), np.empty(n)
    for k in range(m):
        chain = k if rotations.shape[0] > 1 else 0
        start = k if starts.shape[0] > 1 else 0
        _points_linear(
            rotations[chain],
            shifts[chain],
            starts[start],
            cos_q,
            sin_q,
            offsets[k],
            values,
            first,
            coefficients[k],
            x0,
            x1,
            x2,
        )
        out[k, :, 0] = x0
        out[k, :, 1] = x1
        out[k, :, 2] = x2
    return out


@_compiled()
def _euler_zyx(yaw, pitch, roll, out):
    """Rz(yaw) Ry(pitch) Rx(roll) into out (3, 3)."""
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    out[0, 0], out[0, 1], out[0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    out[1, 0], out[1, 1], out[1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    out[2, 0], out[2, 1], out[2, 2] = -sp, cp * sr, cp * cr


@_compiled()
def registered_sum_squares(rotations, shifts, start, cos_q, sin_q, every, t_nr, measured):
    """Sum over configurations of |measured_i - T*(theta1) T_NR p_i(theta2)|^2 for m parameter
    vectors every (m, 6 + N) = (x, y, z, alpha, beta, gamma, offsets...): (m,). measured (3, n)."""
    m, joints, n = every.shape[0], cos_q.shape[0], cos_q.shape[1]
    out = np.zeros(m)
    correction = np.empty((3, 3))
    rotation = np.empty((3, 3))
    translation = np.empty(3)
    cos_d = np.empty(joints)
    sin_d = np.empty(joints)
    x0, x1, x2 = np.empty(n), np.empty(n), np.empty(n)
    for k in range(m):
        for j in range(joints):
            cos_d[j] = np.cos(every[k, 6 + j])
            sin_d[j] = np.sin(every[k, 6 + j])
        _euler_zyx(every[k, 3], every[k, 4], every[k, 5], correction)
        for r in range(3):
            translation[r] = every[k, r]
            for c in range(3):
                rotation[r, c] = 0.0
                for h in range(3):
                    rotation[r, c] += correction[r, h] * t_nr[h, c]
                translation[r] += correction[r, c] * t_nr[c, 3]
        _points(rotations, shifts, start, cos_q, sin_q, cos_d, sin_d, x0, x1, x2)
        total = 0.0
        for i in range(n):
            for r in range(3):
                e = measured[r, i] - (
                    rotation[r, 0] * x0[i] + rotation[r, 1] * x1[i] + rotation[r, 2] * x2[i] + translation[r]
                )
                total += e * e
        out[k] = total
    return out


@_compiled()
def metropolis_walk(
    rotations,
    shifts,
    start,
    cos_q,
    sin_q,
    t_nr,
    measured,
    fixed_values,
    free_index,
    theta,
    log_prob,
    steps,
    log_u,
    states,
    log_probs,
):
    """Random-walk Metropolis on the paper's log-posterior (eq. posterior), the loop of
    `samplers._walk` compiled: from (theta (P,) = free parameters and sigma, its log_prob), step i
    proposes theta + steps[i] and accepts when log_u[i] < the log-posterior ratio. Every state
    goes to states (m, P) and log_probs (m,). Returns (accepted, i) with i the first step whose
    log-posterior is NaN (-1 when none): the caller raises. The same arithmetic, in the same
    order, as the paper's model's `BlockModel.log_posterior`, so the chain is the Python loop's to the bit."""
    m, p = steps.shape
    power = -(3 * cos_q.shape[1] + 2)
    every = fixed_values.copy().reshape(1, -1)
    current = theta.copy()
    proposal = np.empty(p)
    lp = log_prob
    accepted = 0
    for i in range(m):
        for k in range(p):
            proposal[k] = current[k] + steps[i, k]
        sigma = proposal[p - 1]
        if sigma <= 0.0:
            lp_proposal = -np.inf
        else:
            for k in range(p - 1):
                every[0, free_index[k]] = proposal[k]
            energy = registered_sum_squares(rotations, shifts, start, cos_q, sin_q, every, t_nr, measured)[0]
            lp_proposal = power * np.log(sigma) - energy / (2.0 * sigma * sigma)
        if lp_proposal != lp_proposal:
            return accepted, i
        if log_u[i] < lp_proposal - lp:
            current[:] = proposal
            lp = lp_proposal
            accepted += 1
        states[i] = current
        log_probs[i] = lp
    return accepted, -1


@_compiled(fastmath={"contract"})
def orientation_residuals(rotations, tail, sensor, angles, measured):
    """A full-pose probe's residual rotations log(M_i P_ki^T) as rotation vectors (m, n, 3) rad,
    P_ki = sensor[k] rotations[0] Rz(angles[k, i, 0]) ... rotations[N-1] Rz(angles[k, i, N-1]) tail:
    rotations (N, 3, 3) the kernel form's; tail (3, 3) the last basis's transpose, the tool's and
    the probe's rotations; sensor (m, 3, 3); angles (m, n, N) rad; measured M (n, 3, 3).
    `remaster.robot.kinematics.flange_rotations` and `spatial.matrix_to_rotation_vector` are the
    reference."""
    m, n, joints = angles.shape
    out = np.empty((m, n, 3))
    r = np.empty((3, 3))
    t = np.empty((3, 3))
    for k in range(m):
        for i in range(n):
            r[:, :] = sensor[k]
            for j in range(joints):
                for a in range(3):
                    for b in range(3):
                        t[a, b] = (
                            r[a, 0] * rotations[j, 0, b] + r[a, 1] * rotations[j, 1, b] + r[a, 2] * rotations[j, 2, b]
                        )
                c, s = np.cos(angles[k, i, j]), np.sin(angles[k, i, j])
                for a in range(3):
                    r[a, 0] = c * t[a, 0] + s * t[a, 1]
                    r[a, 1] = c * t[a, 1] - s * t[a, 0]
                    r[a, 2] = t[a, 2]
            for a in range(3):
                for b in range(3):
                    t[a, b] = r[a, 0] * tail[0, b] + r[a, 1] * tail[1, b] + r[a, 2] * tail[2, b]
            # e = M t^T: only its antisymmetric part and trace are needed
            e = measured[i]
            e10 = e[1, 0] * t[0, 0] + e[1, 1] * t[0, 1] + e[1, 2] * t[0, 2]
            e01 = e[0, 0] * t[1, 0] + e[0, 1] * t[1, 1] + e[0, 2] * t[1, 2]
            e20 = e[2, 0] * t[0, 0] + e[2, 1] * t[0, 1] + e[2, 2] * t[0, 2]
            e02 = e[0, 0] * t[2, 0] + e[0, 1] * t[2, 1] + e[0, 2] * t[2, 2]
            e21 = e[2, 0] * t[1, 0] + e[2, 1] * t[1, 1] + e[2, 2] * t[1, 2]
            e12 = e[1, 0] * t[2, 0] + e[1, 1] * t[2, 1] + e[1, 2] * t[2, 2]
            trace = 0.0
            for a in range(3):
                trace += e[a, 0] * t[a, 0] + e[a, 1] * t[a, 1] + e[a, 2] * t[a, 2]
            v0, v1, v2 = 0.5 * (e21 - e12), 0.5 * (e02 - e20), 0.5 * (e10 - e01)
            sine = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            angle = np.arctan2(sine, 0.5 * (trace - 1.0))
            ratio = 1.0 + angle * angle / 6.0 if sine < 1e-8 else angle / sine
            out[k, i, 0], out[k, i, 1], out[k, i, 2] = ratio * v0, ratio * v1, ratio * v2
    return out
