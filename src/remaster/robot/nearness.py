"""How near a configuration is to the configurations a calibration measured, in the metric that
matters: how far the marker moves.

The distance between two configurations q and q' is sum_j r_j |d_j|, d_j the difference of joint j
(wrapped to [-pi, pi]) and r_j its lever arm, the largest distance from joint j's axis to the
marker over the measured configurations: to first order at most how far the marker moves when the
joints move from q' to q (each joint moves it by at most r_j |d_j|, and the motions add at most
in length). A configuration's distance to the data is its distance to the
nearest measured configuration. It is *inside* when that distance is at most the data's own
spacing, `radius`: the 95th percentile of each measured configuration's distance to its nearest
other one (configurations of one pose, its IK solutions, count apart), so that a configuration
inside is as near to the data as the data are to each other.

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
    wrapped to [-pi, pi]; a joint without a lever arm has the coordinate 0. The nearest measured
    configuration is then found in log(m) per query, not by comparing with every one of m."""

    def __init__(self, lever: np.ndarray):
        self.lever = np.asarray(lever, dtype=float)
        self.box = np.where(self.lever > 0.0, 2.0 * np.pi * self.lever, 1.0)

    def coordinates(self, q: np.ndarray) -> np.ndarray:
        out = np.mod(np.atleast_2d(q) * self.lever, self.box)
        return np.where(out >= self.box, 0.0, out)  # np.mod may round up to the box itself


@dataclass(frozen=True, eq=False)
class Nearness:
    """measured (m, N) rad: the configurations the calibration used; lever (N,) m: each joint's
    lever arm (`lever_arms`); radius m: the data's spacing (module docstring)."""

    measured: np.ndarray
    lever: np.ndarray
    radius: float

    @classmethod
    def of(cls, chain: KinematicChain, q, marker) -> Nearness:
        """The nearness to readings q (m, N) rad, m >= 1, of a marker (3,) m in the flange frame."""
        q = np.unique(np.atleast_2d(np.asarray(q, dtype=float)), axis=0)
        lever = lever_arms(chain, q, marker)
        if len(q) < 2:
            return cls(q, lever, 0.0)
        spacing = cls(q, lever, 0.0)._nearest(q, exclude_self=True)
        return cls(q, lever, float(np.quantile(spacing, SPACING_QUANTILE)))

    @cached_property
    def _tree(self) -> tuple:
        """The metric and a tree of the measured configurations' distinct points in it (scipy's,
        imported here: the jobs that only read results import this module and no solver)."""
        from scipy.spatial import cKDTree

        metric = _Metric(self.lever)
        return metric, cKDTree(np.unique(metric.coordinates(self.measured), axis=0), boxsize=metric.box)

    def _nearest(self, q: np.ndarray, exclude_self: bool = False) -> np.ndarray:
        """(n,) m: each of q's distance to the nearest measured configuration; with exclude_self (q
        measured ones), to the nearest at a distance above 0 (the tree holds distinct points, so the
        second neighbour of a measured point is the nearest other)."""
        metric, tree = self._tree
        out = np.full(len(q), np.nan)  # a configuration with a non-finite angle (none reached) has none
        finite = np.isfinite(q).all(axis=1)
        if exclude_self and tree.n < 2:
            out[finite] = np.inf
        elif finite.any():
            distances, _ = tree.query(metric.coordinates(q[finite]), k=2 if exclude_self else 1, p=1)
            out[finite] = distances[:, 1] if exclude_self else distances
        return out

    def distance(self, q) -> np.ndarray:
        """(n,) m: each configuration's distance to the nearest measured one."""
        return self._nearest(np.atleast_2d(np.asarray(q, dtype=float)))

    def held_joints(self, width: float = HELD_WIDTH) -> dict[int, float]:
        """{joint index: its value} of the joints the measured configurations never moved: readings
        spanning less than `width` rad (as `evaluation.domain` holds a joint), taken about the first
        reading so that a span across +-pi is not a turn."""
        spread = np.ptp(wrap_angle(self.measured - self.measured[:1]), axis=0)
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
