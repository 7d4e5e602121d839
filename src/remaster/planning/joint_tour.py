"""The order in which a robot program visits its configurations: small joint moves, fewer beam breaks.

A laser tracker loses its beam when the arm reconfigures widely between two measurements, and
an operator must then re-acquire it by hand: the cost of a campaign is in its large moves. A
robot program moves between configurations with synchronised joint moves (URScript `movej`,
KRL `PTP`, RAPID `MoveAbsJ`): every joint starts and stops together, so a move lasts as long as
its largest joint motion takes, and the marker sweeps furthest when one joint turns far.

The cost of a move from configuration a to b is therefore its largest joint motion, the
Chebyshev distance max_j |b_j - a_j| (rad), and the cost of an order is the sum over its moves.
The order is an open path that starts at a given configuration (the first one given, by
default). It is built by the planner's greedy tour (`robot.planning.nearest_neighbour_tour`) with
this cost, then improved by 2-opt (reverse a stretch of the path wherever that shortens it)
until no reversal gains more than `TOLERANCE` or `max_sweeps` sweeps have run. Neither step
loses or repeats a configuration: the result is a permutation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..robot.planning import nearest_neighbour_tour

TOLERANCE = 1e-12  # rad: a reversal must shorten the path by more than this (no cycling on rounding)
MAX_SWEEPS = 50  # 2-opt sweeps over every stretch; each costs O(n^2 N): 1,000 rows take about 1 s in all


def move_costs(q, order=None) -> np.ndarray:
    """Cost (rad) of each move (n - 1,) of configurations q (n, N) visited in `order` (n,)
    (default: as given): the largest joint motion of the move."""
    q = np.asarray(q, dtype=float)
    if order is not None:
        q = q[np.asarray(order, dtype=int)]
    if len(q) < 2:
        return np.zeros(0)
    return np.max(np.abs(np.diff(q, axis=0)), axis=1)


@dataclass(frozen=True)
class JointTour:
    """A visiting order of n configurations and what its moves cost.

    order: (n,) int, the given rows in visiting order (a permutation of 0..n-1);
    moves: (n - 1,) rad, the largest joint motion of each move (move k goes to order[k + 1]);
    method: 'tour' (nearest neighbour + 2-opt) or 'as-given'.
    """

    order: np.ndarray
    moves: np.ndarray
    method: str

    @property
    def total(self) -> float:
        """Sum of the moves' largest joint motions (rad)."""
        return float(self.moves.sum())

    @property
    def largest(self) -> float:
        """The largest joint motion of any move (rad); 0 for fewer than two configurations."""
        return float(self.moves.max()) if len(self.moves) else 0.0


def _chebyshev(q, point) -> np.ndarray:
    return np.max(np.abs(q - point), axis=-1)


def greedy_order(q, first: int = 0) -> np.ndarray:
    """Nearest-neighbour order (n,) of configurations q (n, N) rad from row `first`, by the largest
    joint motion (`robot.planning.nearest_neighbour_tour` over the other rows); a tie goes to the
    lower row."""
    q = np.asarray(q, dtype=float)
    if len(q) == 0:
        return np.zeros(0, dtype=int)
    rest = np.delete(np.arange(len(q)), first)
    return np.r_[first, rest[nearest_neighbour_tour(q[rest], q[first], _chebyshev)]].astype(int)


def two_opt(q, order, max_sweeps: int = MAX_SWEEPS) -> np.ndarray:
    """`order` (n,) of configurations q (n, N) improved by 2-opt on the open path with its first
    configuration fixed: reverse order[i..k] (1 <= i < k) when that lowers the summed move cost
    by more than TOLERANCE, the best reversal for each i in turn, until a sweep finds none or
    `max_sweeps` sweeps have run. The cost is symmetric, so a reversal changes two moves only."""
    q = np.asarray(q, dtype=float)
    order = np.array(order, dtype=int)
    n = len(order)
    if n < 3:
        return order
    path = q[order]
    edges = _chebyshev(path[1:], path[:-1])  # edges[m]: the move from path[m] to path[m + 1]
    for _ in range(max_sweeps):
        improved = False
        for i in range(1, n - 1):
            # reversing path[i..k] replaces the moves (i-1, i) and (k, k+1) by (i-1, k) and (i, k+1)
            k = np.arange(i + 1, n)
            old = edges[i - 1] + np.append(edges[k[:-1]], 0.0)
            new = _chebyshev(path[k], path[i - 1]) + np.append(_chebyshev(path[k[:-1] + 1], path[i]), 0.0)
            gain = old - new
            best = int(np.argmax(gain))
            if gain[best] > TOLERANCE:
                end = k[best]
                order[i : end + 1] = order[i : end + 1][::-1]
                path[i : end + 1] = path[i : end + 1][::-1]
                edges[i:end] = edges[i:end][::-1]
                edges[i - 1] = _chebyshev(path[i], path[i - 1])
                if end < n - 1:
                    edges[end] = _chebyshev(path[end + 1], path[end])
                improved = True
        if not improved:
            break
    return order


def joint_tour(q, method: str = "tour", first: int = 0, max_sweeps: int = MAX_SWEEPS) -> JointTour:
    """The visiting order of configurations q (n, N) rad: 'tour' (nearest neighbour from row
    `first`, then 2-opt) or 'as-given' (rows in their order)."""
    q = np.asarray(q, dtype=float)
    if method == "as-given":
        order = np.arange(len(q))
    elif method == "tour":
        order = two_opt(q, greedy_order(q, first), max_sweeps)
    else:
        raise ValueError(f"unknown order {method!r}: 'tour' or 'as-given'")
    return JointTour(order, move_costs(q, order), method)
