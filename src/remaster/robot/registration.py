"""Rigid registration of a sensor frame N to the robot frame R from corresponding points.

Two methods: the paper's three-point construction (a frame built on three non-collinear
points measured in both frames, after Marvel et al. 2016) and a least-squares fit over all
points (Kabsch/Horn). Both return T_NR (4, 4), mapping robot-frame points into the sensor frame:
p_N = T_NR p_R.
"""

from __future__ import annotations

import numpy as np

from .. import spatial
from ..errors import InputError

# Below this triangle height (m) three points are treated as collinear: the frame they span
# would amplify millimetre noise into degrees.
MIN_SPREAD = 1e-3


def _checked(points, name: str, minimum: int) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"expected an (n, 3) array of points, got shape {p.shape}", key=name)
    bad = np.flatnonzero(~np.all(np.isfinite(p), axis=1))
    if bad.size:
        raise InputError("non-finite point coordinates", key=name, rows=bad)
    if len(p) < minimum:
        raise InputError(f"registration needs at least {minimum} points, got {len(p)}", key=name)
    return p


def _frame_on(points: np.ndarray) -> np.ndarray:
    """Right-handed frame with origin at points[0], x towards points[1], z normal to the plane."""
    x = points[1] - points[0]
    x /= np.linalg.norm(x)
    z = np.cross(x, points[2] - points[0])
    z /= np.linalg.norm(z)
    return spatial.homogeneous(np.column_stack([x, np.cross(z, x), z]), points[0])


def triangle_height(points) -> float:
    """Smallest height (m) of the triangle of three points: 0 when collinear."""
    p = np.asarray(points, dtype=float)
    area2 = np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
    longest = max(np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[2] - p[0]), np.linalg.norm(p[2] - p[1]))
    return 0.0 if longest == 0 else float(area2 / longest)


def three_point(points_robot, points_sensor) -> np.ndarray:
    """T_NR from exactly three non-collinear corresponding points (3, 3) in R and in N.

    More than three points are refused rather than silently cut to the first three (use
    `spread_out_triple` to choose three, or `kabsch` to use them all)."""
    robot = _checked(points_robot, "points_robot", 3)
    sensor = _checked(points_sensor, "points_sensor", 3)
    for name, p in (("points_robot", robot), ("points_sensor", sensor)):
        if len(p) != 3:
            raise InputError(
                f"the three-point registration takes exactly 3 points, got {len(p)} (choose three with "
                f"spread_out_triple, or use kabsch for all of them)",
                key=name,
            )
    for name, p in (("points_robot", robot), ("points_sensor", sensor)):
        if triangle_height(p) < MIN_SPREAD:
            raise InputError(
                f"the three registration points are (nearly) collinear: triangle height "
                f"{triangle_height(p) * 1e3:.3f} mm < {MIN_SPREAD * 1e3:.1f} mm",
                key=name,
            )
    return _frame_on(sensor) @ spatial.invert(_frame_on(robot))


def kabsch(points_robot, points_sensor, weights=None) -> np.ndarray:
    """Least-squares T_NR over n >= 3 corresponding points (n, 3), optionally weighted (n,): one set
    of `rigid_transforms`, its points and weights checked."""
    robot = _checked(points_robot, "points_robot", 3)
    sensor = _checked(points_sensor, "points_sensor", 3)
    if robot.shape != sensor.shape:
        raise InputError(f"{len(robot)} robot points but {len(sensor)} sensor points", key="points_sensor")
    w = np.ones(len(robot)) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (len(robot),):
        raise InputError(f"expected {len(robot)} weights, one per point, got shape {w.shape}", key="weights")
    bad = np.flatnonzero(~np.isfinite(w) | (w < 0))
    if bad.size:
        raise InputError("weights must be finite and not negative", key="weights", rows=bad)
    if not w.sum() > 0:
        raise InputError("every weight is zero", key="weights")
    w = w / w.sum()
    _, singular, _ = np.linalg.svd(robot - w @ robot, full_matrices=False)
    if singular[1] < MIN_SPREAD * np.sqrt(len(robot)) * 1e-3:
        raise InputError("the registration points are (nearly) collinear", key="points_robot")
    return rigid_transforms(robot, sensor[None], w)[0]


def kabsch_with_marker(
    flange_poses, marker, points_sensor, noise: float, marker_std: float, iterations: int = 100
) -> tuple[np.ndarray, np.ndarray]:
    """The registration T_NR (4, 4) and the marker (3,) m in the flange frame fitted together to a
    sensor's points (n, 3) m at flange poses (n, 4, 4) in the robot frame: the most probable pair
    under the marker's Gaussian prior N(marker, marker_std^2 I) and isotropic noise `noise` (m per
    axis). Kabsch with the marker fixed and the marker's linear solve with the rotation fixed
    (the translation eliminated), in turn, until the marker moves less than a nanometre.

    A marker is a campaign's set-up, like the registration: remounted, it moves. What the flange's
    orientations do not turn (one tool orientation: a marker offset is then a translation of the
    registration) stays at its prior value, so a design that cannot tell keeps the marker it was given.
    """
    poses = np.asarray(flange_poses, dtype=float)
    measured = np.asarray(points_sensor, dtype=float)
    rotations, positions = poses[:, :3, :3], poses[:, :3, 3]
    prior = np.asarray(marker, dtype=float)
    if not (np.isfinite(noise) and noise > 0 and np.isfinite(marker_std) and marker_std > 0):
        raise InputError(f"noise {noise} m and marker std {marker_std} m must be positive", key="marker_std")
    turned = rotations - rotations.mean(axis=0)  # (n, 3, 3): the flange's turning about its mean
    moved = positions - positions.mean(axis=0)
    information = np.einsum("nji,njk->ik", turned, turned) + (noise / marker_std) ** 2 * np.eye(3)
    current = prior
    for _ in range(iterations):
        sensor_from_robot = kabsch(spatial.transform_points(poses, current), measured)
        rotation = sensor_from_robot[:3, :3]
        # the sensor's points in the robot frame's axes, centred: turned_i m = those - moved_i
        aligned = (measured - measured.mean(axis=0)) @ rotation - moved
        updated = np.linalg.solve(
            information, np.einsum("nji,nj->i", turned, aligned) + (noise / marker_std) ** 2 * prior
        )
        step = np.linalg.norm(updated - current)
        current = updated
        if step < 1e-9:
            break
    return kabsch(spatial.transform_points(poses, current), measured), current


def rigid_transforms(source, target, weights=None) -> np.ndarray:
    """The transforms T (m, 4, 4) of `rigid_fits` (same arguments): target ~ T source."""
    rotations, centre_s, centre_t = rigid_fits(source, target, weights)
    out = np.tile(np.eye(4), (len(rotations), 1, 1))
    out[:, :3, :3] = rotations
    out[:, :3, 3] = centre_t - (rotations @ centre_s[:, :, None])[:, :, 0]
    return out


def rigid_fits(source, target, weights=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The least-squares rigid motions (Kabsch/Horn, closed form) of m sets of source points onto m
    sets of target points: target ~ R (source - c_source) + c_target. source (n, 3) or (m, n, 3),
    target (m, n, 3) m (the source broadcast over the sets); weights (n,) summing to 1, or None for
    equal weights. Returns rotations R (m, 3, 3) (proper: never a reflection) and the centres
    c_source, c_target (m, 3) m (weighted means). No checks: `kabsch` checks one set."""
    target = np.asarray(target, dtype=float)
    source = np.asarray(source, dtype=float)  # one set (n, 3) is centred once, not once per target set
    if weights is None:
        centre_s, centre_t = source.mean(axis=-2), target.mean(axis=-2)
    else:
        w = np.asarray(weights, dtype=float)
        centre_s, centre_t = w @ source, w @ target
    a, b = source - centre_s[..., None, :], target - centre_t[:, None]
    a_t = np.swapaxes(a if weights is None else a * w[:, None], -1, -2)
    u, _, vt = np.linalg.svd(a_t @ b)  # (m, 3, 3) covariances; matmul, not einsum: 10x faster
    v, ut = np.swapaxes(vt, -1, -2), np.swapaxes(u, -1, -2)
    flip = np.ones((len(target), 3))
    flip[:, 2] = np.sign(np.linalg.det(v @ ut))
    return v @ (flip[:, :, None] * ut), np.broadcast_to(centre_s, centre_t.shape).copy(), centre_t


# Up to this many points the farthest pair is found among all pairs (n^2 / 2 distances, 25 MB at
# this size); beyond, among the convex hull's vertices only, with the same answer.
ALL_PAIRS_UP_TO = 1024
_PAIRS_PER_BLOCK = 2**20  # distances held at once by the blocked search


def _first_farthest(q: np.ndarray, candidates: np.ndarray) -> tuple[int, int]:
    """(i, j), i < j, of the candidates (sorted indices of q) farthest apart, the first such pair
    in (i, j) order on ties; blocked so memory stays at _PAIRS_PER_BLOCK distances."""
    points = q[candidates]
    best, pair = -1.0, (0, 0)
    block = max(1, _PAIRS_PER_BLOCK // max(len(points), 1))
    for start in range(0, len(points), block):
        distances = np.linalg.norm(points[start : start + block, None] - points[None], axis=-1)
        a, b = np.unravel_index(np.argmax(distances), distances.shape)
        if distances[a, b] > best:  # strictly: an earlier block keeps a tie
            best, pair = float(distances[a, b]), (start + int(a), int(b))
    a, b = sorted(pair)
    return int(candidates[a]), int(candidates[b])


def _extreme_points(q: np.ndarray) -> np.ndarray:
    """Sorted indices of q that include every extreme point of its convex hull (the vertices, by
    qhull; points in a plane or on a line by their hull in that plane or line), and every point
    at the same coordinates as one of them; every index where qhull cannot say (exact, slower)."""
    from scipy.spatial import ConvexHull, QhullError

    centred = q - q.mean(axis=0)
    _, singular, axes = np.linalg.svd(centred, full_matrices=False)
    rank = int(np.sum(singular > singular[0] * 1e-12)) if singular[0] > 0 else 0
    if rank == 0:  # every point at one place: all pairs are equally far, the first is (0, 0)
        return np.arange(1)
    if rank >= 2:
        try:
            vertices = ConvexHull(q if rank == 3 else centred @ axes[:2].T).vertices
        except QhullError:  # degenerate in a way the rank missed: every point stays a candidate
            return np.arange(len(q))
    else:
        along = centred @ axes[0]
        vertices = np.array([np.argmin(along), np.argmax(along)])
    rows = np.ascontiguousarray(q).view(np.dtype((np.void, q.dtype.itemsize * 3))).ravel()
    return np.flatnonzero(np.isin(rows, rows[vertices]))


def farthest_pair(points) -> tuple[int, int]:
    """(i, j), i < j: the two rows of points (n, 3) farthest apart, the first such pair in
    (i, j) order when several are equally far. Memory and time grow as n (plus the hull's
    vertices squared): the ends of a diameter are extreme points of the convex hull."""
    q = np.asarray(points, dtype=float)
    candidates = np.arange(len(q)) if len(q) <= ALL_PAIRS_UP_TO else _extreme_points(q)
    return _first_farthest(q, candidates)


def spread_out_triple(points) -> np.ndarray:
    """Indices (3,) of three points far apart: the two farthest apart, then the point farthest
    from the line through them. Deterministic; rows with non-finite coordinates are skipped."""
    p = np.asarray(points, dtype=float)
    usable = np.flatnonzero(np.all(np.isfinite(p), axis=1))
    if usable.size < 3:
        raise InputError(f"registration needs three measured points, found {usable.size}", key="x, y, z")
    q = p[usable]
    i, j = farthest_pair(q)
    direction = (q[j] - q[i]) / max(float(np.linalg.norm(q[j] - q[i])), 1e-300)
    offsets = q - q[i]
    from_line = np.linalg.norm(offsets - (offsets @ direction)[:, None] * direction, axis=1)
    k = int(np.argmax(from_line))
    triple = usable[[min(i, j), max(i, j), k]]
    if triangle_height(p[triple]) < MIN_SPREAD:
        raise InputError("every measured point lies on one line: no frame can be registered", key="x, y, z")
    return triple
