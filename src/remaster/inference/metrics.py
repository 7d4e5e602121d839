"""The paper's accuracy metrics (section Quantifying Positional Accuracy) as array functions.

Arrays in, arrays out, SI throughout (m, rad); the stage that turns them into tables in mm is
`remaster.evaluation.accuracy`. Every summary of errors is `error_summary` (one vocabulary of
statistics: mean, rmse, q2.5, q97.5, p95, count), shown in mm through `in_mm` where a table is made.

- relative accuracy (eq. dist_equation): within each group of configurations that reached the
  same Cartesian pose, how much the distance between two measured marker positions differs from
  the distance the robot's model gives. Distances do not depend on the frame, so the measured
  points stay in the sensor frame and the robot's in the robot frame: no registration is involved.
- post-registration accuracy (eq. post_reg_accuracy): ||E_i|| = ||p_ref,i - p_robot,i||, both in
  the sensor frame, per configuration.
- theoretical accuracy (section theor_acc): distances between the TCP (marker) given by one set
  of zero-offsets (the MLE, or the controller's for Vernier) and the TCPs given by posterior
  draws, with or without the draw's isotropic Gaussian error added.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..campaigns.capacity import THEORETICAL_PAIRS
from ..robot import registration
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..units import MM
from .bounds import QUANTILE

# the statistics `error_summary` knows: name -> the quantile it is, None for a moment
STATISTICS = {"mean": None, "rmse": None, "q2.5": 0.025, "q97.5": 0.975, "p95": QUANTILE}
INTERVAL = ("mean", "q2.5", "q97.5")  # the paper's: the mean and its 95 % interval
Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile: a 95 % interval is mean +- Z95 std


def relative_errors(p_ref, p_robot, groups) -> np.ndarray:
    """d_ij = | ||p_ref,i - p_ref,j|| - ||p_robot,i - p_robot,j|| | for every pair i < j of rows in
    the same group (eq. dist_equation), in m, shape (k,) with k = sum over groups of c (c - 1) / 2
    for c usable rows in the group.

    p_ref (n, 3) measured positions (any frame, e.g. the sensor's); p_robot (n, 3) the model's
    positions (any frame, e.g. the robot's); groups (n,) integer labels, e.g. one per (set, pose).
    Rows with a NaN in either position are skipped (the caller counts them). Pairs are ordered by
    group label, then by row.
    """
    p_ref = np.asarray(p_ref, dtype=float)
    p_robot = np.asarray(p_robot, dtype=float)
    groups = np.asarray(groups)
    if p_ref.shape != p_robot.shape or p_ref.ndim != 2 or p_ref.shape[1] != 3 or groups.shape != p_ref.shape[:1]:
        raise ValueError(
            f"p_ref {p_ref.shape} and p_robot {p_robot.shape} must be (n, 3) and groups (n,), got groups {groups.shape}"
        )
    usable = np.flatnonzero(np.all(np.isfinite(p_ref), axis=1) & np.all(np.isfinite(p_robot), axis=1))
    # the usable rows sorted by group, each group's in row order; then the groups of each size at
    # once (a million-row campaign has 250,000 poses: neither a pass over the rows per group nor a
    # Python step per group)
    ordered = usable[np.argsort(groups[usable], kind="stable")]
    _, starts, sizes = np.unique(groups[ordered], return_index=True, return_counts=True)
    pairs = sizes * (sizes - 1) // 2
    offsets = np.cumsum(pairs) - pairs  # where each group's pairs begin in the output
    out = np.empty(int(pairs.sum()))
    for size in np.unique(sizes[sizes > 1]):
        of_size = sizes == size
        rows = ordered[starts[of_size][:, None] + np.arange(size)]  # (groups, size)
        i, j = np.triu_indices(size, k=1)
        measured = np.linalg.norm(p_ref[rows[:, i]] - p_ref[rows[:, j]], axis=-1)
        modelled = np.linalg.norm(p_robot[rows[:, i]] - p_robot[rows[:, j]], axis=-1)
        out[offsets[of_size][:, None] + np.arange(len(i))] = np.abs(measured - modelled)
    return out


def post_registration_errors(p_ref, p_pred) -> np.ndarray:
    """||E_i|| = ||p_ref,i - p_pred,i|| (m), shape (n,), for positions (n, 3) in the same frame
    (eq. post_reg_accuracy per configuration). NaN where either position is NaN."""
    p_ref = np.asarray(p_ref, dtype=float)
    p_pred = np.asarray(p_pred, dtype=float)
    if p_ref.shape != p_pred.shape or p_ref.shape[-1] != 3:
        raise ValueError(f"p_ref {p_ref.shape} and p_pred {p_pred.shape} must both be (n, 3)")
    return np.linalg.norm(p_ref - p_pred, axis=-1)


def error_summary(errors, statistics: Sequence[str] = INTERVAL) -> dict[str, float | int]:
    """The one summary of errors (any shape, flattened; m, or any one unit): the `statistics` asked,
    in that order, then `count`, of the finite errors, in the errors' unit. The vocabulary:
    'mean'; 'rmse' (root mean square); 'q2.5', 'q97.5' (the ends of the paper's 95 % interval);
    'p95' (the 95th percentile). No finite error: count 0 and NaN statistics (never an error).
    Tables show it through `in_mm`."""
    unknown = [s for s in statistics if s not in STATISTICS]
    if unknown:
        raise ValueError(f"unknown statistics {unknown}: the summary knows {list(STATISTICS)}")
    values = np.asarray(errors, dtype=float).ravel()
    values = values[np.isfinite(values)]  # a copy of the caller's values: partitioned in place below
    if values.size == 0:
        return {**{s: np.nan for s in statistics}, "count": 0}
    out = {}
    for name in statistics:  # the moments before the partition reorders the values
        if name == "mean":
            out[name] = float(values.mean())
        elif name == "rmse":
            out[name] = float(np.sqrt(np.mean(values**2)))
    quantiles = [s for s in statistics if STATISTICS[s] is not None]
    if quantiles:
        # in place: a second copy of 140 million errors (2000 draws at 70,000 configurations) is 1.1 GB
        found = np.quantile(values, [STATISTICS[s] for s in quantiles], overwrite_input=True)
        out.update({s: float(v) for s, v in zip(quantiles, found)})
    return {**{s: out[s] for s in statistics}, "count": int(values.size)}


def in_mm(summary: Mapping[str, float | int]) -> dict[str, float | int]:
    """An `error_summary` of errors in m as a table shows it: each statistic in mm, named
    '<statistic>_mm', and count, in the summary's order."""
    return {(k if k == "count" else f"{k}_mm"): (v if k == "count" else v / MM) for k, v in summary.items()}


def rms_per_axis(residuals) -> np.ndarray:
    """RMS per axis of residual vectors (..., n, 3): sqrt of the mean square over rows and axes, in
    their unit (the RMSE of `error_summary` over sqrt 3)."""
    return np.sqrt(np.mean(np.asarray(residuals, dtype=float) ** 2, axis=(-2, -1)))


def probable_tcps(chain: KinematicChain, q, marker, draws_offsets, draws_sigma, rng: np.random.Generator) -> np.ndarray:
    """TCPs (m, n, 3) in the robot frame (m) for m zero-offset draws (m, N) at configurations
    q (n, N) rad, marker (3,) m in the flange frame; with draws_sigma (m,) m, each draw's
    isotropic Gaussian error N(0, sigma^2 I3) is added (it is isotropic, so it may be added in
    any frame); with None, the zero-offsets alone."""
    draws_offsets = np.atleast_2d(np.asarray(draws_offsets, dtype=float))
    tcps = ForwardKinematics(chain, q).points(marker, draws_offsets)
    if draws_sigma is not None:
        sigma = np.asarray(draws_sigma, dtype=float)
        if sigma.shape != (len(draws_offsets),):
            raise ValueError(f"draws_sigma must have shape ({len(draws_offsets)},), got {sigma.shape}")
        tcps = tcps + sigma[:, None, None] * rng.standard_normal(tcps.shape)
    return tcps


def theoretical_errors(
    chain: KinematicChain, q, marker, reference_offsets, draws_offsets, draws_sigma, rng: np.random.Generator
) -> np.ndarray:
    """Theoretical positioning errors (m), shape (m * n,), draw-major: the distance between the
    TCP given by reference_offsets (N,) (the MLE, or zeros for Vernier) and the TCP of each of m
    posterior draws (m, N), at each configuration q (n, N), all in the robot frame (the
    registration does not move TCPs relative to each other, so it plays no part). Above
    THEORETICAL_PAIRS pairs, a systematic sample of them (`theoretical_stride`): draw i at the
    configurations i mod k, i mod k + k, ..., shape (about THEORETICAL_PAIRS,).

    draws_sigma (m,) m adds each draw's isotropic Gaussian error (table
    theor_accuracy_measure_all); None gives the error of the zero-offsets alone (table
    theor_accuracy_measure). rng draws the Gaussian error.
    """
    q = np.asarray(q, dtype=float)
    draws_offsets = np.atleast_2d(np.asarray(draws_offsets, dtype=float))
    sigma = None if draws_sigma is None else np.asarray(draws_sigma, dtype=float)
    if sigma is not None and sigma.shape != (len(draws_offsets),):
        raise ValueError(f"draws_sigma must have shape ({len(draws_offsets)},), got {sigma.shape}")
    stride = theoretical_stride(len(draws_offsets), len(q))
    out = []
    for first in range(min(stride, len(draws_offsets))):
        at = q[first::stride]
        reference = ForwardKinematics(chain, at).points(marker, np.asarray(reference_offsets, dtype=float))
        drawn = np.arange(first, len(draws_offsets), stride)
        # a block of draws at a time: the TCPs of all draws at all configurations would take m n 3
        # doubles (3.4 GB for 2000 draws at 70,000 configurations); the Gaussian errors come from rng
        # in the same order either way (draw-major), so the numbers are the same
        block = max(1, TCPS_PER_BLOCK // max(len(reference), 1))
        for start in range(0, len(drawn), block):
            part = drawn[start : start + block]
            tcps = probable_tcps(chain, at, marker, draws_offsets[part], None if sigma is None else sigma[part], rng)
            out.append(np.linalg.norm(tcps - reference, axis=-1).ravel())
    return np.concatenate(out) if out else np.empty(0)


TCPS_PER_BLOCK = 2**20  # TCPs held at once by theoretical_errors (24 MB)


def theoretical_stride(draws: int, configurations: int) -> int:
    """k of `theoretical_errors`' sample: 1 (every pair) up to THEORETICAL_PAIRS pairs, else the
    smallest k that brings them to at most that many; every configuration is still reached (by
    every k-th draw) as long as there are at least k draws."""
    return max(1, math.ceil(draws * configurations / THEORETICAL_PAIRS))


def joint_space_bounds(chain: KinematicChain) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) joint limits (N,) rad, with -pi / +pi where a limit is infinite."""
    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    return lower, upper


def random_configurations(chain: KinematicChain, n: int, rng: np.random.Generator) -> np.ndarray:
    """n configurations (n, N) rad drawn uniformly within the joint limits (+-pi for an
    unlimited joint): the paper's random configurations across the full joint space."""
    lower, upper = joint_space_bounds(chain)
    return rng.uniform(lower, upper, (n, chain.n_joints))


def registered_distances(model_points, reference_points) -> np.ndarray:
    """Distances (m, n) m between model points (n, 3) or (m, n, 3) and m sets of reference points
    (m, n, 3) after the least-squares rigid motion of the model's points onto each set (Kabsch,
    batched: `robot.registration.rigid_fits`): the error a sensor registered over these n points would see."""
    reference = np.asarray(reference_points, dtype=float)
    model = np.asarray(model_points, dtype=float)
    rotations, centre_m, centre_r = registration.rigid_fits(model, reference)
    # one model set (n, 3) is centred once; each set's rotation then applies to it by broadcasting
    a = model - (centre_m[:, None] if model.ndim == 3 else centre_m[0])
    error = a @ np.swapaxes(rotations, 1, 2)
    error -= reference - centre_r[:, None]
    return np.sqrt(np.einsum("...i,...i->...", error, error))
