"""Analytic inverse kinematics of 7-joint S-R-S arms (KUKA LBR iiwa and alike): every solution.

A 7-joint arm is S-R-S when axes 1 and 2 meet at a shoulder point S and axes 5, 6 and 7 meet
at a wrist point W. With the redundancy fixed by the value of joint 3 (q3 = 0 by default), a
flange pose has up to 8 solutions: 2 elbow x 2 shoulder x 2 wrist branches.

Method: product of exponentials with Paden-Kahan subproblems, everything derived from the chain
at q = 0 (axis directions w_j, points r_j on the axes, M = T(0)), so no sign convention of a
particular robot is hard-coded. For a target pose g (base frame):

    T(q) = exp(xi_1 q_1) ... exp(xi_7 q_7) M

1. p_W = g M^-1 W: the wrist joints leave W fixed, so p_W = e1 e2 e3 e4 W.
2. q4 (subproblem 3): e1, e2 leave S fixed, so |e4 W - e3^-1 S| = |p_W - S|; up to 2 roots.
3. q1, q2 (subproblem 2): e1 e2 (e3 e4 W) = p_W; up to 2 roots.
4. q5, q6 (subproblem 2 on directions): R5 R6 w_7 = R_rest w_7 with R_rest = (R1..R4)^T R(g M^-1).
5. q7 (subproblem 1): R7 = (R5 R6)^T R_rest.

Singular poses have a one-parameter family of solutions; one member is returned per family
(so the returned set stays finite), and the two roots that meet there merge into one with
branch label 0:

- shoulder singular (wrist centre on axis 1): q1 is free. It is set to 0; with
  `within_limits=True`, when no solution of that elbow branch is within the limits at q1 = 0,
  q1 is searched on a 1 deg grid instead and, per wrist branch, the solution within limits
  that is most central (least sum of squared joint positions relative to the half ranges) is
  kept. (Stretched upright arm: axes 1, 3 and 5 align, so this moves part of q5 to q1.)
- wrist singular (axes 5 and 7 aligned, q6 = 0 on the iiwa): only q5 + q7 (or q5 - q7) is
  determined; the free angle is split evenly, |q5| = |q7| <= pi/2, which stays within the iiwa
  limits whatever the pose.
- elbow stretched or folded: the two q4 roots coincide. Roots within about 1e-6 rad of it are
  snapped onto it (pose error < 1e-12 m; the other joints absorb the change exactly).

Near (not at) a shoulder or wrist singularity, where the two exact roots are less than
`tolerance` apart, the merged root is returned as well: the exact roots then put the free
angle wherever rounding sends it, possibly outside the limits. Known limitation: close to
two singularities at once (e.g. |q4| < 1e-5 and |q6| < 1e-5) or on a joint limit close to a
singularity, rounding of order 1e-16 / (distance to the singularity) can move a solution
that is within limits just outside them, so it is filtered.

Angles are wrapped to (-pi, pi]. With `within_limits=True`, equivalents q +- 2 pi k that lie
within a joint's limits are added too (none for the iiwa, whose limits are all below 180 deg;
joint 3 is the caller's and is returned as given). Each candidate is checked with forward
kinematics and dropped unless it reproduces the pose to `tolerance` (a safety net, not the
method). Lengths in m, angles in rad.
"""

from __future__ import annotations

import itertools

import numpy as np

from .. import spatial
from .kinematics import ForwardKinematics, KinematicChain

TWO_PI = 2.0 * np.pi
DUPLICATE_TOLERANCE = 1e-9  # rad: solutions closer than this (every joint) are the same solution
_COS_OUT_OF_REACH = 1e-9  # subproblem 3 cosine beyond +-1 by more than this: no root
_COS_SNAP = 1e-12  # subproblem 3 cosine within this of +-1: one (stretched/folded) root


def wrap_angle(q):
    """Angles wrapped to (-pi, pi], same shape as q."""
    return np.pi - np.mod(np.pi - np.asarray(q, dtype=float), TWO_PI)


def _unit(v):
    return v / np.linalg.norm(v)


def _line_intersection(r1, w1, r2, w2):
    """Closest approach of two lines r + t w: (midpoint, distance), or (None, inf) when parallel."""
    n = np.cross(w1, w2)
    if np.linalg.norm(n) < 1e-9:
        return None, np.inf
    (t1, t2), *_ = np.linalg.lstsq(np.column_stack([w1, -w2]), r2 - r1, rcond=None)
    p1, p2 = r1 + t1 * w1, r2 + t2 * w2
    return 0.5 * (p1 + p2), float(np.linalg.norm(p1 - p2))


def _distance_to_line(p, r, w):
    d = p - r
    return float(np.linalg.norm(d - (d @ w) * w))


def _subproblem1(w, u, v, tol):
    """Angle theta with rot(w, theta) u = v (vectors from a point on the axis); 0 when u or v lies
    on the axis (any angle then does, or none: the caller guarantees consistency).
    Returns (theta, free)."""
    up = u - (w @ u) * w
    vp = v - (w @ v) * w
    if np.linalg.norm(up) < tol or np.linalg.norm(vp) < tol:
        return 0.0, True
    return float(np.arctan2(w @ np.cross(up, vp), up @ vp)), False


def _subproblem2(w1, w2, u, v, tol, near=0.0):
    """Roots of rot(w1, t1) rot(w2, t2) u = v, axes through a common point, u and v from it.

    Returns a list of (label, t1, t2, t1_free). z = rot(w2, t2) u = rot(w1, -t1) v is
    a w1 + b w2 + g n (n = w1 x w2); label +1 for g n on the side of w2 x w1, -1 for the other
    side. The two roots are |g n| from the merged point g = 0 (label 0): below `tol` only the
    merged root is returned; below `near` (> tol) it is returned as well as the two roots, as an
    approximate solution the caller checks (near a singularity the exact roots may put the free
    angle anywhere, e.g. outside the joint limits, while the merged one splits it sensibly).
    """
    c = w1 @ w2
    n = np.cross(w1, w2)
    s2 = 1.0 - c * c
    a1 = w1 @ v  # = w1 . z
    a2 = w2 @ u  # = w2 . z
    alpha = (a1 - c * a2) / s2
    beta = (a2 - c * a1) / s2
    v1 = np.linalg.norm(v - a1 * w1)  # distance of v from axis 1
    u2 = np.linalg.norm(u - a2 * w2)  # distance of u from axis 2
    # gamma^2 from |z_perp1| = |v_perp1| or from |z_perp2| = |u_perp2| (equal when |u| = |v|):
    # take the one whose cancellation is harmless, i.e. match exactly the smaller perpendicular
    # distance, so the rounding mismatch lands on the larger one (accurate near singularities).
    if v1 <= u2:
        g2 = v1 * v1 / s2 - beta * beta
    else:
        g2 = u2 * u2 / s2 - alpha * alpha
    near = max(near, tol)
    if g2 * s2 < -near * near:  # no real root, not even approximately
        return []
    g = np.sqrt(max(g2, 0.0))
    spread = g * np.sqrt(s2)  # |g n|: distance of either root from the merged point
    branches = []
    if spread > tol:
        branches += [(1, -g), (-1, g)]
    if spread <= near:
        branches.append((0, 0.0))
    roots = []
    for label, gamma in branches:
        z = alpha * w1 + beta * w2 + gamma * n
        t2, _ = _subproblem1(w2, u, z, tol)
        t1, free = _subproblem1(w1, z, v, tol)
        roots.append((label, t1, t2, free))
    return roots


def _subproblem3(w, r, p, q, delta, tol):
    """Roots of |rot_about_line(r, w, theta) p - q| = delta (points).

    Returns a list of (label, theta): label +1 / -1 for a positive / negative rotation away
    from the configuration where the distance is largest (the stretched elbow), 0 when the two
    roots coincide (stretched or folded).
    """
    u, v = p - r, q - r
    up = u - (w @ u) * w
    vp = v - (w @ v) * w
    nu, nv = np.linalg.norm(up), np.linalg.norm(vp)
    d2 = delta * delta - (w @ (u - v)) ** 2
    if nu < tol or nv < tol:  # the distance does not depend on theta: all angles or none
        return [(0, 0.0)] if abs(np.linalg.norm(u - v) - delta) < tol else []
    theta0 = np.arctan2(w @ np.cross(up, vp), up @ vp)
    cos_angle = (nu * nu + nv * nv - d2) / (2.0 * nu * nv)  # cos(theta0 - theta)
    if abs(cos_angle) > 1.0 + _COS_OUT_OF_REACH:
        return []
    stretched = theta0 + np.pi  # rot(theta) u' antiparallel to v': largest distance
    if cos_angle <= -1.0 + _COS_SNAP:
        return [(0, float(stretched))]
    if cos_angle >= 1.0 - _COS_SNAP:
        return [(0, float(theta0))]
    b = np.arccos(-cos_angle)  # rotation away from stretched, in (0, pi)
    return [(1, float(stretched + b)), (-1, float(stretched - b))]


class SRSInverseKinematics:
    """All analytic inverse kinematics solutions of a 7-joint S-R-S chain for a fixed q3.

    Built once per chain (checks the geometry, raises ValueError when the chain is not S-R-S:
    7 revolute joints, axes 1 and 2 intersecting, axes 5, 6 and 7 intersecting in one point).
    The chain's axes must intersect to `geometry_tolerance` (m), so a calibrated chain whose
    axes miss each other slightly needs numerical IK instead.
    """

    def __init__(self, chain: KinematicChain, geometry_tolerance: float = 1e-10):
        if chain.n_joints != 7:
            raise ValueError(f"S-R-S inverse kinematics needs 7 joints, chain {chain.name!r} has {chain.n_joints}")
        self.chain = chain
        zero = np.zeros((1, 7))
        fk = ForwardKinematics(chain, zero)
        frames = fk.joint_frames()[0]  # (7, 4, 4) joint frames at q = 0
        # Rotation is about the joint frame's origin, so that origin lies on the axis.
        w = np.einsum("jab,jb->ja", frames[:, :3, :3], chain.joint_axes)
        self.axes = w / np.linalg.norm(w, axis=1, keepdims=True)  # (7, 3) w_j, base frame
        self.points = frames[:, :3, 3].copy()  # (7, 3) r_j, base frame
        self.home = fk.flange_poses()[0]  # (4, 4) M = T(0)
        self.home_inverse = spatial.invert(self.home)

        tol = geometry_tolerance
        shoulder, dist = _line_intersection(self.points[0], self.axes[0], self.points[1], self.axes[1])
        if shoulder is None or dist > tol:
            raise ValueError(
                f"chain {chain.name!r} is not S-R-S: axes 1 and 2 do not intersect "
                f"({'parallel' if shoulder is None else f'{dist:.3g} m apart'})"
            )
        wrist, dist = _line_intersection(self.points[4], self.axes[4], self.points[5], self.axes[5])
        if wrist is None or dist > tol:
            raise ValueError(
                f"chain {chain.name!r} is not S-R-S: axes 5 and 6 do not intersect "
                f"({'parallel' if wrist is None else f'{dist:.3g} m apart'})"
            )
        dist = _distance_to_line(wrist, self.points[6], self.axes[6])
        if dist > tol:
            raise ValueError(
                f"chain {chain.name!r} is not S-R-S: axis 7 misses the intersection of axes 5 and 6 by {dist:.3g} m"
            )
        if np.linalg.norm(np.cross(self.axes[5], self.axes[6])) < 1e-9:
            raise ValueError(f"chain {chain.name!r} is not S-R-S: axes 6 and 7 are parallel")
        if _distance_to_line(wrist, self.points[3], self.axes[3]) < 1e-6:
            raise ValueError(f"chain {chain.name!r} is not S-R-S: the wrist centre lies on axis 4 (no elbow)")
        self.shoulder = shoulder  # (3,) S, m
        self.wrist = wrist  # (3,) W at q = 0, m
        # Lengths are compared with 1e-10 of the arm's size (a pose error far below 1e-9 m).
        self._tol_len = 1e-10 * max(1.0, float(np.linalg.norm(wrist - shoulder)))
        self._tol_dir = 1e-10
        # A unit vector normal to axis 7, to read q7 from a rotation about it.
        x = np.cross(self.axes[6], np.eye(3)[np.argmin(np.abs(self.axes[6]))])
        self._x7 = _unit(x)
        self._y7 = np.cross(self.axes[6], self._x7)

    # ------------------------------------------------------------------ exponentials

    def _rotation(self, j, theta):
        return spatial.rot_axis(self.axes[j], theta)

    def _screw(self, j, theta):
        """exp(xi_j theta): rotation about axis j through r_j, (4, 4)."""
        rotation = self._rotation(j, theta)
        return spatial.homogeneous(rotation, self.points[j] - rotation @ self.points[j])

    # ------------------------------------------------------------------ solve

    def solve(
        self, pose, q3: float = 0.0, within_limits: bool = True, tolerance: float = 1e-9, return_branches: bool = False
    ):
        """All joint configurations (k, 7) (rad) whose flange pose is `pose` (4, 4, base frame, m).

        q3 (rad) fixes the redundancy and is returned as given. Solutions are sorted by branch
        label (shoulder, elbow, wrist), +1 before 0 before -1, then by angle; k = 0 (shape
        (0, 7)) when the pose is out of reach for this q3 or every solution violates the joint
        limits (`within_limits=True`). Every returned row reproduces the pose to `tolerance`
        (m for the position, rotation-matrix entries); a pose that is not rigid to that
        tolerance therefore yields no solution.

        Branch labels (k, 3) ints, returned as a second value with `return_branches=True`:
        elbow +1 / -1 = rotation of joint 4 positive / negative away from the stretched arm
        (the sign of q4 on the iiwa); shoulder and wrist +1 / -1 = the two roots of
        subproblem 2 (the wrist label is the sign of q6 on the iiwa); 0 = merged at a
        singularity. How singular poses are resolved: see the module docstring.
        """
        g = np.asarray(pose, dtype=float)
        if g.shape != (4, 4):
            raise ValueError(f"pose must be a 4x4 homogeneous transform, got shape {g.shape}")
        if not np.all(np.isfinite(g)):
            raise ValueError("pose has non-finite entries")
        q3 = float(q3)
        if not np.isfinite(q3):
            raise ValueError("q3 must be finite")
        chain = self.chain
        empty = (np.empty((0, 7)), np.empty((0, 3), dtype=int))
        if within_limits and not (chain.lower[2] - 1e-12 <= q3 <= chain.upper[2] + 1e-12):
            return empty if return_branches else empty[0]

        w, tol_len = self.axes, self._tol_len
        S, W = self.shoulder, self.wrist
        gm = g @ self.home_inverse  # e1 ... e7
        p_wrist = gm[:3, :3] @ W + gm[:3, 3]
        e3 = self._screw(2, q3)
        s_moved = spatial.transform_points(spatial.invert(e3), S)  # e3^-1 S
        reach = float(np.linalg.norm(p_wrist - S))

        candidates, labels = [], []
        for elbow, q4 in _subproblem3(w[3], self.points[3], W, s_moved, reach, tol_len):
            e34 = e3 @ self._screw(3, q4)
            elbow_wrist = spatial.transform_points(e34, W)
            shoulder_roots = _subproblem2(w[0], w[1], elbow_wrist - S, p_wrist - S, tol_len, near=tolerance)
            for shoulder, q1, q2, free in shoulder_roots:
                rows = self._complete(q1, q2, q3, q4, e34, gm, tolerance)
                if free and within_limits and all(self._spread(row) is None for _, row in rows):
                    rows = self._free_shoulder(q2, q3, q4, e34, gm, tolerance)
                for wrist, row in rows:
                    candidates.append(row)
                    labels.append((shoulder, elbow, wrist))
        if not candidates:
            return empty if return_branches else empty[0]

        wrapped = np.array(candidates)
        labels = np.array(labels, dtype=int)
        # Safety net: keep what reproduces the pose.
        poses = ForwardKinematics(chain, wrapped).flange_poses()
        error = np.maximum(
            np.abs(poses[:, :3, 3] - g[:3, 3]).max(axis=1), np.abs(poses[:, :3, :3] - g[:3, :3]).max(axis=(1, 2))
        )
        keep = np.isfinite(error) & (error <= tolerance)
        wrapped, labels = wrapped[keep], labels[keep]

        rows = []
        for qi, li in zip(wrapped, labels):
            if any(np.all(np.abs(wrap_angle(qi - qk)) <= DUPLICATE_TOLERANCE) for qk, _ in rows):
                continue
            rows.append((qi, li))
        if within_limits:
            rows = [(alt, li) for qi, li in rows for alt in self._equivalents(qi)]
        if not rows:
            return empty if return_branches else empty[0]
        rows.sort(key=lambda row: (tuple(-row[1]), tuple(row[0])))
        result = (np.array([r[0] for r in rows]), np.array([r[1] for r in rows], dtype=int))
        return result if return_branches else result[0]

    def _complete(self, q1, q2, q3, q4, e34, gm, tolerance):
        """Wrist joints for given q1..q4: list of (wrist label, [q1, ..., q7])."""
        w = self.axes
        r14 = self._rotation(0, q1) @ self._rotation(1, q2) @ e34[:3, :3]
        r_rest = r14.T @ gm[:3, :3]  # = R5 R6 R7
        target = r_rest @ w[6]
        rows = []
        for wrist, q5, q6, free in _subproblem2(w[4], w[5], w[6], target, self._tol_dir, near=tolerance):
            if free:
                # Axes 5 and 7 aligned: only q5 + sigma q7 is fixed (sigma = +-1 as the axes
                # are parallel or antiparallel); split it evenly, which keeps both far from
                # their limits (|q5| = |q7| <= pi/2).
                sigma = 1.0 if w[4] @ target > 0 else -1.0
                phi = sigma * self._q7(q5, q6, r_rest)
                q5 = 0.5 * float(wrap_angle(phi))
            rows.append((wrist, wrap_angle(np.array([q1, q2, q3, q4, q5, q6, self._q7(q5, q6, r_rest)]))))
        for _, row in rows:
            row[2] = q3  # the caller's value, not wrapped
        return rows

    def _free_shoulder(self, q2, q3, q4, e34, gm, tolerance):
        """Wrist centre on axis 1 and q1 = 0 violates the limits: q1 on a 1 deg grid, keeping per
        wrist label the row within limits that is most central (`_spread`; ties: smallest |q1|)."""
        grid = np.deg2rad(np.arange(-179, 181))
        grid = grid[np.lexsort((-grid, np.abs(grid)))]  # 0, 1, -1, 2, -2, ... deg
        best: dict[int, tuple[float, np.ndarray]] = {}
        for q1 in grid:
            for wrist, row in self._complete(q1, q2, q3, q4, e34, gm, tolerance):
                spread = self._spread(row)
                if spread is not None and (wrist not in best or spread < best[wrist][0]):
                    best[wrist] = (spread, row)
        return [(wrist, row) for wrist, (_, row) in sorted(best.items(), reverse=True)]

    def _spread(self, row):
        """Sum over joints with finite limits of ((q - mid) / half range)^2, best over the 2 pi
        equivalents within limits; None when none is within limits."""
        lower, upper = self.chain.lower, self.chain.upper
        finite = np.isfinite(lower) & np.isfinite(upper)
        mid, half = 0.5 * (upper + lower)[finite], 0.5 * (upper - lower)[finite]
        spreads = [float(np.sum(((alt[finite] - mid) / half) ** 2)) for alt in self._equivalents(row)]
        return min(spreads) if spreads else None

    def _q7(self, q5, q6, r_rest):
        """q7 with rot(w7, q7) = (R5 R6)^T r_rest, read on a vector normal to axis 7."""
        r7 = (self._rotation(4, q5) @ self._rotation(5, q6)).T @ r_rest
        x = r7 @ self._x7
        return float(np.arctan2(self._y7 @ x, self._x7 @ x))

    def _equivalents(self, q):
        """q and its q_j +- 2 pi k variants within the joint limits (joint 3 left alone);
        empty when some joint has no value within its limits."""
        lower, upper, tol = self.chain.lower, self.chain.upper, 1e-12
        options = []
        for j, value in enumerate(q):
            if j == 2 or not (np.isfinite(lower[j]) and np.isfinite(upper[j])):
                values = [value] if (lower[j] - tol <= value <= upper[j] + tol) else []
            else:
                k_lo = int(np.ceil((lower[j] - tol - value) / TWO_PI))
                k_hi = int(np.floor((upper[j] + tol - value) / TWO_PI))
                values = [value + TWO_PI * k for k in range(k_lo, k_hi + 1)]
            if not values:
                return []
            options.append(values)
        return [np.array(combo) for combo in itertools.product(*options)]
