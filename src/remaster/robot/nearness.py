"""How near a configuration is to the configurations a calibration measured, in the metric that
matters: how far the marker moves.

The distance between two configurations q and q' is sum_j r_j |d_j|, d_j the difference of joint j
(below) and r_j its lever arm, the largest distance from joint j's axis to the marker over the
measured configurations: to first order at most how far the marker moves when the joints move from
q' to q (each joint moves it by at most r_j |d_j|, and the motions add at most in length). A
configuration's distance to the data is its distance to the nearest measured configuration. It is
*inside* when that distance is at most the data's own spacing, `radius`: the 95th percentile of
each measured configuration's distance to its nearest other one (configurations of one pose, its
IK solutions, count apart), so that a configuration inside is as near to the data as the data are
to each other.

A revolute joint's difference is taken on the circle (wrapped to [-pi, pi]): the geometry, gravity's
torque, a joint's cyclic error and the residual GP's kernel are periodic in each joint, so a reading
one turn away (a UR reaches a pose with q1 or q1 - 2 pi) is the same configuration. A model that
corrects in proportion to the reading itself (a joint scale: s_j q_j) is not periodic in that joint:
q_j + 2 pi gets a correction 2 pi s_j larger, which no measurement near it determined. Such joints
are `linear`: their difference is the readings' own, so one turn away is far (`turns` says where
a configuration near on the circle is a turn away in such a joint). The chain's joints are all
revolute (`kinematics` refuses a prismatic one), so every other joint is on the circle.

SI inside (m, rad).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .ik import wrap_angle
from .kinematics import ForwardKinematics, KinematicChain

SPACING_QUANTILE = 0.95  # the data's spacing: this quantile of the nearest-neighbour distances
HELD_WIDTH = np.radians(0.01)  # rad: readings spanning less: the joint was held (a controller's jitter, not a motion)
NO_LEVER = 1e-9  # m: a joint whose lever arm is below moves no marker (the marker on its axis, up to round-off)


def circle_arcs(q) -> tuple[np.ndarray, np.ndarray]:
    """(start (N,), arc (N,)) rad: per joint, the shortest arc of the circle that holds every
    reading of q (m, N), m >= 1: from `start` (wrapped to (-pi, pi]) over `arc` in the positive
    sense, 0 for one value, below 2 pi. It is the circle less the widest gap between neighbouring
    readings: a joint's measured range taken on the circle, where readings one turn apart are one."""
    wrapped = np.sort(wrap_angle(np.atleast_2d(np.asarray(q, dtype=float))), axis=0)
    # the gap after each reading, the last one's running on to the first reading a turn later
    gaps = np.diff(np.vstack([wrapped, wrapped[:1] + 2.0 * np.pi]), axis=0)
    widest = gaps.argmax(axis=0)
    joints = np.arange(wrapped.shape[1])
    start = wrapped[(widest + 1) % len(wrapped), joints]
    return start, 2.0 * np.pi - gaps[widest, joints]


def lever_arms(chain: KinematicChain, q, marker) -> np.ndarray:
    """(N,) m: the largest distance from each joint's axis to the marker over configurations q (n, N)."""
    fk = ForwardKinematics(chain, np.atleast_2d(np.asarray(q, dtype=float)))
    frames = fk.joint_frames()  # (n, N, 4, 4): joint j's axis is chain.joint_axes[j] in its frame
    axes = np.einsum("njab,jb->nja", frames[..., :3, :3], chain.joint_axes)
    offset = fk.points(marker)[:, None, :] - frames[..., :3, 3]
    across = offset - np.sum(offset * axes, axis=-1, keepdims=True) * axes
    return np.linalg.norm(across, axis=-1).max(axis=0)


class _Metric:
    """The metric as a k-d tree's (scipy's cKDTree, L1, periodic): coordinate j is q_j r_j on a
    circle of length 2 pi r_j, so that the tree's periodic L1 distance is sum_j r_j |d_j|, d_j
    wrapped to [-pi, pi]; a `linear` joint's coordinate is q_j r_j on the line (a box of 0: not
    periodic) unless its lever arm is below `NO_LEVER`; a joint without a lever arm's is 0. The
    nearest measured configuration is then found in log(m) per query, not by comparing with every
    one of m."""

    def __init__(self, lever: np.ndarray, linear: tuple[int, ...] = ()):
        self.lever = np.asarray(lever, dtype=float)
        self.on_line = np.isin(np.arange(len(self.lever)), linear) & (self.lever > NO_LEVER)
        self.box = np.where(self.on_line, 0.0, np.where(self.lever > 0.0, 2.0 * np.pi * self.lever, 1.0))

    def coordinates(self, q: np.ndarray) -> np.ndarray:
        scaled = np.atleast_2d(q) * self.lever
        periodic = np.where(self.on_line, 1.0, self.box)  # a linear joint's box of 0 would divide by 0
        circle = np.mod(scaled, periodic)
        circle = np.where(circle >= periodic, 0.0, circle)  # np.mod may round up to the box itself
        return np.where(self.on_line, scaled, circle)


@dataclass(frozen=True, eq=False)
class Nearness:
    """measured (m, N) rad: the configurations the calibration used; lever (N,) m: each joint's
    lever arm (`lever_arms`); radius m: the data's spacing; linear: the joints whose difference is
    the readings' own, not on the circle (module docstring)."""

    measured: np.ndarray
    lever: np.ndarray
    radius: float
    linear: tuple[int, ...] = ()

    @classmethod
    def of(cls, chain: KinematicChain, q, marker, linear=()) -> Nearness:
        """The nearness to readings q (m, N) rad, m >= 1, of a marker (3,) m in the flange frame;
        linear: the joints a model corrects in proportion to their reading (`Calibration.linear_joints`)."""
        q = np.unique(np.atleast_2d(np.asarray(q, dtype=float)), axis=0)
        lever, linear = lever_arms(chain, q, marker), tuple(sorted(int(j) for j in linear))
        if len(q) < 2:
            return cls(q, lever, 0.0, linear)
        spacing = cls(q, lever, 0.0, linear)._nearest(q, exclude_self=True)
        return cls(q, lever, float(np.quantile(spacing, SPACING_QUANTILE)), linear)

    @cached_property
    def _tree(self) -> tuple:
        """The metric, a tree of the measured configurations' distinct points in it (scipy's,
        imported here: the jobs that only read results import this module and no solver) and the
        measured row of each of its points."""
        from scipy.spatial import cKDTree

        metric = _Metric(self.lever, self.linear)
        points, rows = np.unique(metric.coordinates(self.measured), axis=0, return_index=True)
        return metric, cKDTree(points, boxsize=metric.box), rows

    def _query(self, q: np.ndarray, exclude_self: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """((n,) m, (n,) int): each of q's distance to the nearest measured configuration and that
        configuration's row of `measured` (-1 where none); with exclude_self (q measured ones), to
        the nearest at a distance above 0 (the tree holds distinct points, so the second neighbour
        of a measured point is the nearest other)."""
        metric, tree, rows = self._tree
        out = np.full(len(q), np.nan)  # a configuration with a non-finite angle (none reached) has none
        nearest = np.full(len(q), -1)
        finite = np.isfinite(q).all(axis=1)
        if exclude_self and tree.n < 2:
            out[finite] = np.inf
        elif finite.any():
            distances, index = tree.query(metric.coordinates(q[finite]), k=2 if exclude_self else 1, p=1)
            out[finite] = distances[:, 1] if exclude_self else distances
            nearest[finite] = rows[index[:, 1] if exclude_self else index]
        return out, nearest

    def _nearest(self, q: np.ndarray, exclude_self: bool = False) -> np.ndarray:
        """(n,) m: `_query`'s distances."""
        return self._query(q, exclude_self)[0]

    def distance(self, q) -> np.ndarray:
        """(n,) m: each configuration's distance to the nearest measured one."""
        return self._nearest(np.atleast_2d(np.asarray(q, dtype=float)))

    def differences(self, q, reference) -> np.ndarray:
        """(..., N) rad: q - reference per joint as this metric takes it, on the circle (wrapped to
        (-pi, pi]) but for the `linear` joints."""
        raw = np.asarray(q, dtype=float) - np.asarray(reference, dtype=float)
        return np.where(np.isin(np.arange(raw.shape[-1]), self.linear), raw, wrap_angle(raw))

    def on_circle(self) -> Nearness:
        """The same data and spacing with every joint on the circle."""
        return Nearness(self.measured, self.lever, self.radius)

    def turns(self, q) -> np.ndarray:
        """(n, N) int: per configuration, how many whole turns each `linear` joint's reading is from
        the nearest measured configuration on the circle (0 for the other joints, for one without a
        lever arm, and where there is none): where it is not 0, the configuration is near the data on the circle only, and a
        correction in proportion to that reading was not measured there."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        _, nearest = self.on_circle()._query(q)
        out = np.zeros(q.shape, dtype=int)
        found = nearest >= 0
        raw = q[found] - self.measured[nearest[found]]
        out[found] = np.rint((raw - wrap_angle(raw)) / (2.0 * np.pi)).astype(int)
        out[:, ~_Metric(self.lever, self.linear).on_line] = 0  # a joint without a lever arm moves no marker
        return out

    def held_joints(self, width: float = HELD_WIDTH) -> dict[int, float]:
        """{joint index: its value} of the joints the measured configurations never moved: readings
        spanning less than `width` rad (as `evaluation.domain` holds a joint), taken about the first
        reading (`differences`: on the circle, a span across +-pi is not a turn)."""
        spread = np.ptp(self.differences(self.measured, self.measured[:1]), axis=0)
        return {j: float(self.measured[0, j]) for j in range(self.measured.shape[1]) if spread[j] < width}

    def inside(self, q) -> np.ndarray:
        """Boolean (n,): within the data's spacing of a measured configuration."""
        return self.distance(q) <= self.radius

    def draw(self, n: int, rng: np.random.Generator, lower=None, upper=None) -> np.ndarray:
        """n configurations (n, N) rad inside: a measured configuration chosen at random, moved
        uniformly within the ball of radius `radius` of the metric (the lever-weighted L1 ball:
        exponential magnitudes over their sum with one more, random signs), clipped to the limits
        lower, upper (N,) rad when given. A joint with no lever arm (the marker on its axis) does
        not move the marker and is left where it was measured."""
        dims = len(self.lever)
        start = self.measured[rng.integers(len(self.measured), size=n)]
        magnitudes = rng.exponential(size=(n, dims + 1))
        unit = magnitudes[:, :dims] / magnitudes.sum(axis=1, keepdims=True)  # uniform in the unit L1 ball's orthant
        signs = rng.choice([-1.0, 1.0], size=(n, dims))
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(self.lever > 0.0, self.radius * signs * unit / self.lever, 0.0)
        q = start + step
        if lower is not None and upper is not None:
            q = np.clip(q, lower, upper)
        return q
