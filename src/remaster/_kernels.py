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
def _registration(every, t_nr, rotation, translation):
    """The registration of parameters every (6 + N,): rotation (3, 3) = C T_NR's and translation
    (3,) = (x, y, z) + C T_NR's, C = Rz Ry Rx of (alpha, beta, gamma), into the arrays given."""
    correction = np.empty((3, 3))
    _euler_zyx(every[3], every[4], every[5], correction)
    for r in range(3):
        translation[r] = every[r]
        for c in range(3):
            rotation[r, c] = 0.0
            for h in range(3):
                rotation[r, c] += correction[r, h] * t_nr[h, c]
            translation[r] += correction[r, c] * t_nr[c, 3]


@_compiled()
def registered_sum_squares(rotations, shifts, start, cos_q, sin_q, every, t_nr, measured):
    """Sum over configurations of |measured_i - T*(theta1) T_NR p_i(theta2)|^2 for m parameter
    vectors every (m, 6 + N) = (x, y, z, alpha, beta, gamma, offsets...): (m,). measured (3, n)."""
    m, joints, n = every.shape[0], cos_q.shape[0], cos_q.shape[1]
    out = np.zeros(m)
    rotation = np.empty((3, 3))
    translation = np.empty(3)
    cos_d = np.empty(joints)
    sin_d = np.empty(joints)
    x0, x1, x2 = np.empty(n), np.empty(n), np.empty(n)
    for k in range(m):
        for j in range(joints):
            cos_d[j] = np.cos(every[k, 6 + j])
            sin_d[j] = np.sin(every[k, 6 + j])
        _registration(every[k], t_nr, rotation, translation)
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


@_compiled(fastmath={"contract"})
def _expand_configuration(rotations, shifts, start, c_ref, s_ref, terms, norms, matrix):
    """One configuration's marker position as a polynomial in w_j = (1, cos delta_j - 1,
    sin delta_j), delta the zero-offsets' departure from a reference: Rz(phi + delta) = Rz(phi)
    (I + (cos delta - 1) E1 + sin delta E2), E1 = diag(1, 1, 0), E2 x = (-x1, x0, 0), so the
    position is multilinear in the w_j: terms (3^N, 3), term a = sum_j a_j 3^j. norms (3^N,): the
    same of |position|^2, multilinear too as the joints' rotations keep lengths: |R Rz y + s|^2 =
    |y|^2 + |s|^2 + 2 s.R Rz y. c_ref, s_ref (N,): cos and sin of each joint's reference angle
    (reading and reference offset); matrix (3, 3) scratch."""
    terms[0, :] = start
    norms[0] = start[0] * start[0] + start[1] * start[1] + start[2] * start[2]
    count = 1
    for j in range(rotations.shape[0] - 1, -1, -1):
        r, shift, c, s = rotations[j], shifts[j], c_ref[j], s_ref[j]
        for row in range(3):
            matrix[row, 0] = r[row, 0] * c + r[row, 1] * s
            matrix[row, 1] = r[row, 1] * c - r[row, 0] * s
            matrix[row, 2] = r[row, 2]
        for a in range(count - 1, -1, -1):  # downwards: term a is read before 3a .. 3a + 2 are written
            v0, v1, v2, carried = terms[a, 0], terms[a, 1], terms[a, 2], norms[a]
            for d in range(3):
                x0, x1, x2 = (v0, v1, v2) if d == 0 else ((v0, v1, 0.0) if d == 1 else (-v1, v0, 0.0))
                out = 3 * a + d
                cross = 0.0
                for row in range(3):
                    value = matrix[row, 0] * x0 + matrix[row, 1] * x1 + matrix[row, 2] * x2
                    terms[out, row] = value
                    cross += shift[row] * value
                norms[out] = 2.0 * cross + (carried if d == 0 else 0.0)
        norms[0] += shift[0] * shift[0] + shift[1] * shift[1] + shift[2] * shift[2]
        for row in range(3):
            terms[0, row] += shift[row]
        count *= 3


@_compiled(fastmath={"contract"})
def expansion_sums(rotations, shifts, start, cos_q, sin_q, reference, t_nr, measured):
    """The sums over configurations that give the paper's sum of squares at any parameters
    (`expanded_sum_squares`) in a time that does not grow with them. reference (6 + N,) the
    parameters the expansion is about; measured (3, n). Returns (cross (3^N, 3, 3) = sum_i e_i
    P_ia^T, mixed (3^N, 3, 3) = sum_i P_ia P_i0^T, linear (3^N, 3) = sum_i P_ia, square (3^N,) =
    sum_i (|p_i|^2's term a - 2 P_ia.P_i0), totals = (sum |e_i|^2, sum e_i (3), n)): P_ia the terms
    of configuration i's robot-frame position (`_expand_configuration`), e_i its residual at the
    reference. Every sum is of quantities that vanish with the departure from the reference or
    with the residuals, so the sum of squares is assembled without cancelling large numbers."""
    joints, n = cos_q.shape
    size = 3**joints
    cross, mixed = np.zeros((size, 3, 3)), np.zeros((size, 3, 3))
    linear, square, totals = np.zeros((size, 3)), np.zeros(size), np.zeros(5)
    terms, norms, matrix = np.empty((size, 3)), np.empty(size), np.empty((3, 3))
    rotation, translation = np.empty((3, 3)), np.empty(3)
    _registration(reference, t_nr, rotation, translation)
    c_ref, s_ref = np.empty(joints), np.empty(joints)
    cos_o, sin_o = np.cos(reference[6:]), np.sin(reference[6:])
    e = np.empty(3)
    for i in range(n):
        for j in range(joints):
            c_ref[j] = cos_q[j, i] * cos_o[j] - sin_q[j, i] * sin_o[j]
            s_ref[j] = sin_q[j, i] * cos_o[j] + cos_q[j, i] * sin_o[j]
        _expand_configuration(rotations, shifts, start, c_ref, s_ref, terms, norms, matrix)
        for row in range(3):
            e[row] = measured[row, i] - translation[row]
            for col in range(3):
                e[row] -= rotation[row, col] * terms[0, col]
            totals[0] += e[row] * e[row]
            totals[1 + row] += e[row]
        p0, p1, p2 = terms[0, 0], terms[0, 1], terms[0, 2]
        for a in range(size):
            t0, t1, t2 = terms[a, 0], terms[a, 1], terms[a, 2]
            for row in range(3):
                cross[a, row, 0] += e[row] * t0
                cross[a, row, 1] += e[row] * t1
                cross[a, row, 2] += e[row] * t2
            for row, t in ((0, t0), (1, t1), (2, t2)):
                mixed[a, row, 0] += t * p0
                mixed[a, row, 1] += t * p1
                mixed[a, row, 2] += t * p2
                linear[a, row] += t
            square[a] += norms[a] - 2.0 * (t0 * p0 + t1 * p1 + t2 * p2)
    totals[4] = n
    return cross, mixed, linear, square, totals


@_compiled(fastmath={"contract"})
def expanded_sum_squares(expansion, every, t_nr):
    """`registered_sum_squares` from the sums of `expansion_sums` (expansion = its five arrays and
    the reference): for m parameter vectors every (m, 6 + N), (m,). With r_i = e_i - u_i - v_i,
    u_i = dR P_i0 + dt (the registration's change, dR = R - R_ref from the difference of the
    two corrections, not of two rotations), v_i = R sum_(a > 0) w^a P_ia (the zero-offsets'):
    sum |e|^2 - 2 sum e.u - 2 sum e.v + sum |u|^2 + 2 sum u.v + sum |v|^2, each a contraction of
    the sums with w^a (`_expand_configuration`), |v_i|^2 by the polynomial of |p_i|^2."""
    cross, mixed, linear, square, totals, reference = expansion
    m, size, joints = every.shape[0], cross.shape[0], every.shape[1] - 6
    out = np.empty(m)
    weights = np.empty(size)
    c_now, c_ref = np.empty((3, 3)), np.empty((3, 3))
    _euler_zyx(reference[3], reference[4], reference[5], c_ref)
    rotation, d_rot, d_t = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    nw, qw, bw = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    for k in range(m):
        _euler_zyx(every[k, 3], every[k, 4], every[k, 5], c_now)
        for r in range(3):
            d_t[r] = every[k, r] - reference[r]
            for c in range(3):
                rotation[r, c] = 0.0
                d_rot[r, c] = 0.0
                for h in range(3):
                    rotation[r, c] += c_now[r, h] * t_nr[h, c]
                    d_rot[r, c] += (c_now[r, h] - c_ref[r, h]) * t_nr[h, c]
                d_t[r] += (c_now[r, c] - c_ref[r, c]) * t_nr[c, 3]
        weights[0] = 1.0
        count = 1
        for j in range(joints - 1, -1, -1):
            delta = every[k, 6 + j] - reference[6 + j]
            half = np.sin(0.5 * delta)
            w1, w2 = -2.0 * half * half, np.sin(delta)
            for a in range(count - 1, -1, -1):
                x = weights[a]
                weights[3 * a], weights[3 * a + 1], weights[3 * a + 2] = x, x * w1, x * w2
            count *= 3
        nw[:, :] = 0.0
        qw[:, :] = 0.0
        bw[:] = 0.0
        lw = 0.0
        for a in range(1, size):
            w = weights[a]
            if w == 0.0:
                continue
            for r in range(3):
                bw[r] += w * linear[a, r]
                for c in range(3):
                    nw[r, c] += w * cross[a, r, c]
                    qw[r, c] += w * mixed[a, r, c]
            lw += w * square[a]
        energy = totals[0] + lw + totals[4] * (d_t[0] * d_t[0] + d_t[1] * d_t[1] + d_t[2] * d_t[2])
        for r in range(3):
            energy -= 2.0 * d_t[r] * totals[1 + r]
            moved = 0.0  # (dR P0 sum).dt and R bw . dt
            for c in range(3):
                energy -= 2.0 * d_rot[r, c] * cross[0, r, c] + 2.0 * rotation[r, c] * nw[r, c]
                moved += d_rot[r, c] * linear[0, c] + rotation[r, c] * bw[c]
                for h in range(3):
                    # |dR P0|^2 and (dR P0).(R P_a): mixed[a][c, h] = sum P_a[c] P0[h]
                    energy += d_rot[r, c] * mixed[0, c, h] * d_rot[r, h]
                    energy += 2.0 * rotation[r, c] * qw[c, h] * d_rot[r, h]
            energy += 2.0 * d_t[r] * moved
        out[k] = energy
    return out


@_compiled(fastmath={"contract"}, inline="always")
def _orientation_residual(rotations, tail, sensor, cos_sin, measured, scratch, out):
    """One reading's residual rotation log(M P^T) as a rotation vector into out (3,) rad, P =
    sensor rotations[0] Rz(a_0) ... rotations[N-1] Rz(a_N-1) tail (`orientation_residuals`), from
    the angles' cosines and sines cos_sin (2, N); scratch (2, 3, 3)."""
    r, t = scratch[0], scratch[1]
    r[:, :] = sensor
    for j in range(cos_sin.shape[1]):
        for a in range(3):
            for b in range(3):
                t[a, b] = r[a, 0] * rotations[j, 0, b] + r[a, 1] * rotations[j, 1, b] + r[a, 2] * rotations[j, 2, b]
        c, s = cos_sin[0, j], cos_sin[1, j]
        for a in range(3):
            r[a, 0] = c * t[a, 0] + s * t[a, 1]
            r[a, 1] = c * t[a, 1] - s * t[a, 0]
            r[a, 2] = t[a, 2]
    for a in range(3):
        for b in range(3):
            t[a, b] = r[a, 0] * tail[0, b] + r[a, 1] * tail[1, b] + r[a, 2] * tail[2, b]
    # e = M t^T: only its antisymmetric part and trace are needed
    e = measured
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
    out[0], out[1], out[2] = ratio * v0, ratio * v1, ratio * v2


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
    scratch = np.empty((2, 3, 3))
    cos_sin = np.empty((2, joints))
    for k in range(m):
        for i in range(n):
            cos_sin[0], cos_sin[1] = np.cos(angles[k, i]), np.sin(angles[k, i])
            _orientation_residual(rotations, tail, sensor[k], cos_sin, measured[i], scratch, out[k, i])
    return out


@_compiled(fastmath={"contract"})
def orientation_sum_squares(rotations, tail, every, t_nr, cos_q, sin_q, measured, weight):
    """The paper's model's orientation part of the sum of squares, weight^2 sum_i |log(M_i P_i^T)|^2
    (`orientation_residuals`), for m parameter vectors every (m, 6 + N) (the registration, then the
    zero-offsets added to the readings, whose cosines and sines are cos_q, sin_q (n, N)): (m,).
    measured M (n, 3, 3)."""
    m, n, joints = every.shape[0], cos_q.shape[0], cos_q.shape[1]
    out = np.zeros(m)
    rotation = np.empty((3, 3))
    translation = np.empty(3)
    cos_d, sin_d = np.empty(joints), np.empty(joints)
    cos_sin = np.empty((2, joints))
    residual = np.empty(3)
    scratch = np.empty((2, 3, 3))
    for k in range(m):
        _registration(every[k], t_nr, rotation, translation)
        for j in range(joints):
            cos_d[j] = np.cos(every[k, 6 + j])
            sin_d[j] = np.sin(every[k, 6 + j])
        total = 0.0
        for i in range(n):
            for j in range(joints):  # cos and sin of q + offset by the angle-sum formulas, as `_points`
                cos_sin[0, j] = cos_q[i, j] * cos_d[j] - sin_q[i, j] * sin_d[j]
                cos_sin[1, j] = sin_q[i, j] * cos_d[j] + cos_q[i, j] * sin_d[j]
            _orientation_residual(rotations, tail, rotation, cos_sin, measured[i], scratch, residual)
            for a in range(3):
                e = weight * residual[a]
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
    expansion,
    orientation,
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
    `sampling.random_walk._walk` compiled: from (theta (P,) = free parameters and sigma, its log_prob), step i
    proposes theta + steps[i] and accepts when log_u[i] < the log-posterior ratio. Every state
    goes to states (m, P) and log_probs (m,). Returns (accepted, i) with i the first step whose
    log-posterior is NaN (-1 when none): the caller raises. The sum of squares by
    `expanded_sum_squares` when expansion (`expansion_sums`' arrays and reference) holds terms,
    else `registered_sum_squares`: the same arithmetic, in the same order, as the paper's model's
    `BlockModel.log_posterior`, so the chain is the Python loop's to the bit. orientation (tail,
    the readings' cosines and sines (n_o, N) each, measured rotations (n_o, 3, 3), weight (1,)): a
    full-pose probe's, whose `orientation_sum_squares` is added (n_o = 0: points alone)."""
    m, p = steps.shape
    tail, orientation_cos, orientation_sin, orientation_measured, orientation_weight = orientation
    power = -(3 * (cos_q.shape[1] + orientation_cos.shape[0]) + 2)
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
            if expansion[0].shape[0] > 0:
                energy = expanded_sum_squares(expansion, every, t_nr)[0]
            else:
                energy = registered_sum_squares(rotations, shifts, start, cos_q, sin_q, every, t_nr, measured)[0]
            if orientation_cos.shape[0] > 0:
                energy += orientation_sum_squares(
                    rotations,
                    tail,
                    every,
                    t_nr,
                    orientation_cos,
                    orientation_sin,
                    orientation_measured,
                    orientation_weight[0],
                )[0]
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
