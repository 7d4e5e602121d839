"""Measurement planning (paper, section Data Collection): which joint configurations to command.

Candidate Cartesian poses come from a Latin hypercube over {angle about base Z, radius, height,
rotation about tool Z}; the tool Z axis points at the reference sensor's origin (eqs. zaxis,
xaxis, yaxis, rotation_new). Every inverse-kinematics solution of every pose is a candidate
configuration; those outside joint limits, below the floor, self-colliding (a capsule model of
the links) or whose marker a link hides from a sensor are discarded, and the rest are ordered
by a nearest-neighbour tour in joint space.

A second design, ISO 9283 cube poses (`plan_cubes`), keeps the positions of the standard's cube
test and one flange orientation for every pose, so the tool axis never changes direction; it
goes through the same checks and tour and gives a table of the same format.

Both hold the 7-axis arm's redundancy, joint 3, at one angle (`q3`, 0 by default), or draw it
uniformly within its limits for each pose (`q3=FREE`). A third design, random joint-space
configurations (`plan_random`), moves every joint within its limits or holds any of them, as
campaigns that hold joints 1 and 7 do, and needs no inverse kinematics (6-axis arms too).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import spatial
from ..errors import InputError
from .ik import SRSInverseKinematics
from .kinematics import ForwardKinematics, KinematicChain

FREE = "free"  # q3 drawn uniformly within joint 3's limits for each pose, not held


@dataclass(frozen=True)
class Workspace:
    """Ranges of the Latin hypercube (m, rad), as in the paper."""

    radius: tuple[float, float] = (0.2, 0.5)
    height: tuple[float, float] = (0.4, 0.8)
    base_angle: tuple[float, float] = (0.0, 2.0 * np.pi)
    tool_angle: tuple[float, float] = (-np.pi, np.pi)


@dataclass(frozen=True)
class SightLine:
    """A sensor that must see a marker: its origin in the robot frame (3,) m, the marker (3,)
    in the flange frame, and the largest angle (rad) between the tool Z axis and the line of
    sight at which the marker is still seen (a retroreflector's acceptance cone)."""

    sensor_origin: np.ndarray
    marker: np.ndarray
    acceptance: float = np.radians(60.0)


@dataclass(frozen=True)
class CollisionModel:
    """Capsules around the segments joining successive joint origins (and the flange), and a
    capsule for the tool plate between two points in the flange frame. Radii in m."""

    link_radius: float = 0.06
    plate_ends: tuple[tuple[float, float, float], ...] = ((0.1, 0.0, 0.02), (-0.1, 0.0, 0.02))
    plate_radius: float = 0.02
    floor_height: float = 0.0
    min_index_gap: int = 3  # segments closer in the chain than this share a joint and always touch


@dataclass(frozen=True)
class SetSize:
    """How many configurations a pointing design plans: Latin hypercubes of `candidates` poses are
    drawn (at most MAX_BATCHES) until `poses` poses with exactly `configurations` configurations
    among them exist; without `poses` and `configurations`, one hypercube, every usable pose kept."""

    candidates: int = 60
    poses: int | None = None
    configurations: int | None = None


MAX_BATCHES = 20  # hypercubes of a pointing design before it gives up
MAX_RANDOM_BATCHES = 50  # batches of random joint-space configurations before `plan_random` gives up


@dataclass
class Plan:
    """Configurations to command: a table with set, pose, solution, q1..qN (rad), and counts of
    what was discarded and why."""

    table: pd.DataFrame
    discarded: dict[str, int] = field(default_factory=dict)
    candidates: int = 0


def latin_hypercube(n: int, dimensions: int, rng: np.random.Generator) -> np.ndarray:
    """n stratified samples in [0, 1)^dimensions: one per row and column stratum."""
    strata = np.array([rng.permutation(n) for _ in range(dimensions)]).T
    return (strata + rng.random((n, dimensions))) / n


def pointing_pose(position, target, tool_angle: float) -> np.ndarray:
    """Flange pose (4, 4) at `position` with its Z axis towards `target`, x = z x Z (normalised),
    y = z x x, then turned by `tool_angle` about its own Z (eqs. zaxis, xaxis, yaxis, rotation_new)."""
    position = np.asarray(position, dtype=float)
    z = np.asarray(target, dtype=float) - position
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-9:  # z vertical: the paper's setup never meets this; any x will do
        x = np.cross(z, [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    rotation = np.column_stack([x, np.cross(z, x), z]) @ spatial.rot_z(tool_angle)
    return spatial.homogeneous(rotation, position)


def candidate_poses(n: int, target, rng: np.random.Generator, workspace: Workspace = Workspace()) -> np.ndarray:
    """n flange poses (n, 4, 4) from a Latin hypercube, each pointing at `target` (3,)."""
    u = latin_hypercube(n, 4, rng)

    def scale(column, bounds):
        return bounds[0] + u[:, column] * (bounds[1] - bounds[0])

    angle, radius = scale(0, workspace.base_angle), scale(1, workspace.radius)
    height, tool = scale(2, workspace.height), scale(3, workspace.tool_angle)
    positions = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), height])
    return np.array([pointing_pose(p, target, t) for p, t in zip(positions, tool)])


def segment_distances(a0, a1, b0, b1) -> np.ndarray:
    """Shortest distances between segments a0-a1 and b0-b1, broadcasting over leading axes (..., 3)."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a = np.einsum("...i,...i", d1, d1)
    e = np.einsum("...i,...i", d2, d2)
    f = np.einsum("...i,...i", d2, r)
    c = np.einsum("...i,...i", d1, r)
    b = np.einsum("...i,...i", d1, d2)
    denom = a * e - b * b
    tiny = 1e-18
    # Ericson, Real-Time Collision Detection, 5.1.9, branch-free over the batch
    s = np.where(denom > tiny, np.clip((b * f - c * e) / np.maximum(denom, tiny), 0.0, 1.0), 0.0)
    s = np.where(a > tiny, s, 0.0)
    t = np.where(e > tiny, (b * s + f) / np.maximum(e, tiny), 0.0)
    t_clamped = np.clip(t, 0.0, 1.0)
    redo = (t != t_clamped) | (e <= tiny)
    s_end = np.where(a > tiny, np.clip((b * t_clamped - c) / np.maximum(a, tiny), 0.0, 1.0), 0.0)
    s = np.where(redo, s_end, s)
    closest_a = a0 + s[..., None] * d1
    closest_b = b0 + t_clamped[..., None] * d2
    return np.linalg.norm(closest_a - closest_b, axis=-1)


def link_segments(chain: KinematicChain, q, model: CollisionModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsule segments (n, S, 2, 3) in the base frame for configurations q (n, N), with radii
    (S,) and chain positions (S,): base-joint 1, joint j - joint j+1, last joint - flange, plate."""
    fk = ForwardKinematics(chain, np.atleast_2d(q))
    frames = fk.joint_frames()
    flange = frames[:, -1] @ chain.tool_transform
    origins = np.concatenate([np.zeros((len(frames), 1, 3)), frames[:, :, :3, 3], flange[:, None, :3, 3]], axis=1)
    links = np.stack([origins[:, :-1], origins[:, 1:]], axis=2)
    plate = spatial.transform_points(flange[:, None], np.asarray(model.plate_ends, dtype=float))
    segments = np.concatenate([links, plate[:, None]], axis=1)
    radii = np.append(np.full(links.shape[1], model.link_radius), model.plate_radius)
    return segments, radii, np.arange(segments.shape[1])


def collision_free(chain: KinematicChain, q, model: CollisionModel) -> tuple[np.ndarray, np.ndarray]:
    """(above_floor, no_self_collision), boolean arrays (n,) for configurations q (n, N)."""
    segments, radii, index = link_segments(chain, q, model)
    moving = segments[:, 2:]  # the base and first link stand on the floor by construction
    above = np.all(moving[..., 2] - radii[2:, None] >= model.floor_height, axis=(1, 2))
    i, j = np.triu_indices(len(index), k=model.min_index_gap)
    distances = segment_distances(segments[:, i, 0], segments[:, i, 1], segments[:, j, 0], segments[:, j, 1])
    return above, np.all(distances >= radii[i] + radii[j], axis=1)


def marker_visible(chain: KinematicChain, q, sight: SightLine, model: CollisionModel) -> np.ndarray:
    """Boolean (n,): the marker faces the sensor within its acceptance cone and no link capsule
    crosses the line of sight."""
    fk = ForwardKinematics(chain, np.atleast_2d(q))
    marker = fk.points(sight.marker)
    to_sensor = np.asarray(sight.sensor_origin, dtype=float) - marker
    to_sensor /= np.linalg.norm(to_sensor, axis=1, keepdims=True)
    tool_z = fk.flange_poses()[:, :3, 2]
    facing = np.einsum("ni,ni->n", tool_z, to_sensor) >= np.cos(sight.acceptance)
    segments, radii, _ = link_segments(chain, q, model)
    links = segments[:, :-1]  # the plate carries the marker
    start = marker[:, None] + to_sensor[:, None] * 1e-6
    end = np.broadcast_to(np.asarray(sight.sensor_origin, dtype=float), start.shape)
    clearance = segment_distances(start, end, links[..., 0, :], links[..., 1, :])
    return facing & np.all(clearance >= radii[None, :-1], axis=1)


def euclidean_distance(q, point) -> np.ndarray:
    """Euclidean joint distances (m,) rad of configurations q (m, N) rad to one, point (N,) rad."""
    return np.linalg.norm(q - point, axis=1)


def nearest_neighbour_tour(q, start=None, distance=euclidean_distance) -> np.ndarray:
    """Order (n,) visiting configurations q (n, N) rad greedily, each time the nearest one left,
    from `start` (N,) rad (default: the first configuration); a tie goes to the lower row.
    distance(q (m, N), point (N,)) -> (m,) rad: Euclidean by default (the planner's tours);
    `planning.joint_tour` passes the largest joint motion."""
    q = np.asarray(q, dtype=float)
    if len(q) == 0:
        return np.zeros(0, dtype=int)
    remaining = list(range(len(q)))
    current = q[0] if start is None else np.asarray(start, dtype=float)
    order = []
    while remaining:
        distances = distance(q[remaining], current)
        nearest = remaining.pop(int(np.argmin(distances)))
        order.append(nearest)
        current = q[nearest]
    return np.array(order)


def choose_poses(counts, n_poses: int, n_configurations: int) -> np.ndarray:
    """Indices of the earliest poses, n_poses of them, whose configuration counts sum to exactly
    n_configurations (a subset-sum by dynamic programming). Raises if no subset fits."""
    counts = np.asarray(counts, dtype=int)
    m = len(counts)
    # feasible[i, p, c]: poses i.. can supply exactly p poses and c configurations
    feasible = np.zeros((m + 1, n_poses + 1, n_configurations + 1), dtype=bool)
    feasible[m, 0, 0] = True
    for i in range(m - 1, -1, -1):
        feasible[i] = feasible[i + 1]
        k = counts[i]
        if k <= n_configurations:
            feasible[i, 1:, k:] |= feasible[i + 1, :-1, : n_configurations + 1 - k]
    if not feasible[0, n_poses, n_configurations]:
        raise InputError(
            f"no {n_poses} of the {m} usable poses give exactly {n_configurations} configurations", key="plan"
        )
    chosen, p, c = [], n_poses, n_configurations
    for i in range(m):
        k = counts[i]
        if p > 0 and k <= c and feasible[i + 1, p - 1, c - k]:
            chosen.append(i)
            p, c = p - 1, c - k
    return np.array(chosen)


def usable_solutions(
    chain: KinematicChain,
    pose,
    sights,
    model: CollisionModel,
    q3: float = 0.0,
    solver: SRSInverseKinematics | None = None,
) -> tuple[np.ndarray, dict[str, int]]:
    """Every inverse-kinematics solution of one flange pose that passes every check, (k, N), and
    how many were discarded for each reason."""
    solver = solver or SRSInverseKinematics(chain)
    every = solver.solve(pose, q3=q3, within_limits=False)
    reasons = {"joint_limits": 0, "floor": 0, "self_collision": 0, "occluded": 0}
    if len(every) == 0:
        return every, reasons
    keep = chain.within_limits(every)
    reasons["joint_limits"] = int((~keep).sum())
    above, apart = collision_free(chain, every, model)
    for name, ok in (("floor", above), ("self_collision", apart)):
        reasons[name] = int((keep & ~ok).sum())
        keep &= ok
    for sight in sights:
        seen = marker_visible(chain, every, sight, model)
        reasons["occluded"] += int((keep & ~seen).sum())
        keep &= seen
    return every[keep], reasons


def joint_range(chain: KinematicChain, joint: int) -> tuple[float, float]:
    """The range (rad) a joint (0-based) is drawn from: its limits, within (-pi, pi] where a
    limit is unknown (a DH table's)."""
    return max(float(chain.lower[joint]), -np.pi), min(float(chain.upper[joint]), np.pi)


def _q3_values(chain: KinematicChain, q3, count: int, rng: np.random.Generator | None) -> np.ndarray:
    """Joint 3's angle (rad) for each of `count` poses: `q3` held, or with q3 = FREE drawn
    uniformly within its limits from rng."""
    if not (isinstance(q3, str) and q3 == FREE):
        return np.full(count, float(q3))
    if rng is None:
        raise ValueError("a free q3 is drawn at random: pass a Generator")
    return rng.uniform(*joint_range(chain, 2), count)


def _usable_poses(
    chain: KinematicChain,
    poses,
    sights,
    model: CollisionModel,
    q3s,
    solver: SRSInverseKinematics,
    poses_out: list,
    discarded: dict,
) -> None:
    """Append the usable solutions (k, N) of each flange pose (4, 4) that has any to `poses_out`,
    joint 3 held at that pose's value of q3s (rad), and add what was discarded, and why, to
    `discarded`."""
    for pose, q3 in zip(poses, q3s):
        solutions, reasons = usable_solutions(chain, pose, sights, model, float(q3), solver)
        for reason, count in reasons.items():
            discarded[reason] = discarded.get(reason, 0) + count
        if len(solutions):
            poses_out.append(solutions)
        else:
            discarded["unreachable_poses"] += 1


def plan_set(
    chain: KinematicChain,
    set_name: str,
    target,
    sights,
    rng: np.random.Generator,
    *,
    size: SetSize = SetSize(),
    model: CollisionModel = CollisionModel(),
    q3: float | str = 0.0,
) -> Plan:
    """Plan one set (optimization or validation) of `size` (`SetSize`): the earliest subset of the
    usable poses of exactly that size is kept. q3 (rad) holds joint 3; FREE draws it for each pose
    after the batch's poses.
    """
    solver = SRSInverseKinematics(chain)
    poses, discarded = [], {"unreachable_poses": 0}
    drawn = 0
    for _ in range(MAX_BATCHES):
        batch = candidate_poses(size.candidates, target, rng)
        drawn += len(batch)
        q3s = _q3_values(chain, q3, len(batch), rng)
        _usable_poses(chain, batch, sights, model, q3s, solver, poses, discarded)
        if size.poses is None:
            break
        counts = [len(s) for s in poses]
        try:
            chosen = choose_poses(counts, size.poses, size.configurations)
            poses = [poses[i] for i in chosen]
            break
        except InputError:
            continue
    else:
        raise InputError(
            f"{set_name}: {MAX_BATCHES} batches of {size.candidates} candidates did not give "
            f"{size.poses} poses with {size.configurations} configurations",
            key="plan",
        )
    return Plan(_toured_table(chain, set_name, poses), discarded, drawn)


# Corners of the cube's diagonal plane, in units of half an edge from its centre along the base
# axes: the lower edge at -x and the upper edge at +x, both parallel to y. Each corner's
# opposite corner on the plane is two places on.
ISO9283_PLANE_CORNERS = np.array([[-1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [1.0, 1.0, 1.0], [1.0, -1.0, 1.0]])
ISO9283_CORNER_FRACTION = 0.1  # P2..P5 lie this fraction of a diagonal in from its ends


def iso9283_points(centre, edge: float) -> np.ndarray:
    """The five ISO 9283 measuring points (5, 3) m of a cube of `edge` m centred at `centre` (3,) m
    with its edges parallel to the base axes: P1 the centre, then P2..P5 on the diagonals of the
    diagonal plane through the cube's lower -x edge and upper +x edge, each 10 % of that
    diagonal (edge * sqrt(3)) in from the corners (-x,-y), (-x,+y), (+x,+y), (+x,-y) in turn."""
    centre = np.asarray(centre, dtype=float)
    corners = centre + 0.5 * float(edge) * ISO9283_PLANE_CORNERS
    opposite = np.roll(corners, 2, axis=0)
    return np.vstack([centre, corners + ISO9283_CORNER_FRACTION * (opposite - corners)])


def cube_orientation(centres, target, tool_angle: float = 0.0) -> np.ndarray:
    """The one flange rotation (3, 3) of a cube campaign: tool Z from the mean of the cube
    centres (k, 3) m towards `target` (3,) m, turned by `tool_angle` rad about it (as
    `pointing_pose`)."""
    return pointing_pose(np.mean(np.atleast_2d(centres), axis=0), target, tool_angle)[:3, :3]


def plan_cubes(
    chain: KinematicChain,
    set_name: str,
    cubes,
    rotation,
    sights,
    *,
    model: CollisionModel = CollisionModel(),
    q3: float | str = 0.0,
    rng: np.random.Generator | None = None,
) -> Plan:
    """Plan one set from ISO 9283 cube poses.

    `cubes` is a sequence of (centre (3,) m, edge m); each cube gives its five ISO 9283 points
    (`iso9283_points`), so a set of c cubes has 5 c candidate poses. Every pose has the flange
    rotation `rotation` (3, 3), the same for the whole campaign (`cube_orientation`), so the data
    never turn the tool axis: the design of a cube test, and what a calibration fitted on it
    lacks. Every usable inverse-kinematics solution of each pose is kept, after the checks of
    `plan_set`; a pose with none is counted as unreachable. The design is fixed: no randomness,
    unless q3 = FREE, drawn for each pose from `rng`.
    """
    rotation = np.asarray(rotation, dtype=float)
    points = (
        np.concatenate([iso9283_points(centre, edge) for centre, edge in cubes]) if len(cubes) else np.zeros((0, 3))
    )
    poses, discarded = [], {"unreachable_poses": 0}
    _usable_poses(
        chain,
        [spatial.homogeneous(rotation, p) for p in points],
        sights,
        model,
        _q3_values(chain, q3, len(points), rng),
        SRSInverseKinematics(chain),
        poses,
        discarded,
    )
    return Plan(_toured_table(chain, set_name, poses), discarded, len(points))


def plan_random(
    chain: KinematicChain,
    set_name: str,
    sights,
    rng: np.random.Generator,
    *,
    n_configurations: int,
    held: dict[int, float] | None = None,
    candidates: int = 200,
    model: CollisionModel = CollisionModel(),
) -> Plan:
    """Plan one set of random joint-space configurations: every joint drawn uniformly within its
    range (`joint_range`), except the `held` ones {joint (0-based): angle (rad), or (low, high) rad:
    drawn within that range instead, one region of joint space, e.g. a joint a turn away}, in batches of
    `candidates` (at most MAX_RANDOM_BATCHES), until `n_configurations` pass the checks of `plan_set`
    (floor, self-collision, every sight line); the first that pass are kept, each its own pose. A real campaign that
    holds joints the inverse kinematics cannot hold (joints 1 and 7 of a 7-axis arm), or of an
    arm without an analytic inverse, is planned this way.
    """
    ranges = np.array([joint_range(chain, j) for j in range(chain.n_joints)])
    for joint, value in (held or {}).items():
        if np.ndim(value) == 1:
            ranges[joint] = value
    held = {joint: angle for joint, angle in (held or {}).items() if np.ndim(angle) == 0}
    kept, discarded, drawn = [], {"floor": 0, "self_collision": 0, "occluded": 0}, 0
    for _ in range(MAX_RANDOM_BATCHES):
        q = rng.uniform(ranges[:, 0], ranges[:, 1], (candidates, chain.n_joints))
        for joint, angle in held.items():
            q[:, joint] = angle
        drawn += candidates
        keep = np.ones(candidates, dtype=bool)
        above, apart = collision_free(chain, q, model)
        for name, ok in (("floor", above), ("self_collision", apart)):
            discarded[name] += int((keep & ~ok).sum())
            keep &= ok
        for sight in sights:
            seen = marker_visible(chain, q, sight, model)
            discarded["occluded"] += int((keep & ~seen).sum())
            keep &= seen
        kept.extend(q[keep])
        if len(kept) >= n_configurations:
            break
    else:
        raise InputError(
            f"{set_name}: {MAX_RANDOM_BATCHES} batches of {candidates} random configurations gave {len(kept)} "
            f"that pass the checks, not {n_configurations}",
            key="plan",
        )
    poses = [row[None] for row in kept[:n_configurations]]
    return Plan(_toured_table(chain, set_name, poses), discarded, drawn)


def _toured_table(chain: KinematicChain, set_name: str, poses) -> pd.DataFrame:
    """Table of configurations in nearest-neighbour tour order; pose and solution numbered in
    order of first visit."""
    q = np.concatenate(poses) if poses else np.zeros((0, chain.n_joints))
    pose_of = np.concatenate([np.full(len(s), i) for i, s in enumerate(poses)]) if poses else np.zeros(0, int)
    order = nearest_neighbour_tour(q, start=np.zeros(chain.n_joints))
    pose_numbers: dict[int, int] = {}
    solution_counts: dict[int, int] = {}
    rows = []
    for i in order:
        pose = pose_numbers.setdefault(int(pose_of[i]), len(pose_numbers))
        solution = solution_counts.get(pose, 0)
        solution_counts[pose] = solution + 1
        rows.append((pose, solution))
    table = pd.DataFrame(
        {
            "set": pd.Series([set_name] * len(order), dtype=object),
            "pose": np.array([r[0] for r in rows], dtype=np.int64),
            "solution": np.array([r[1] for r in rows], dtype=np.int64),
        }
    )
    for j in range(chain.n_joints):
        table[f"q{j + 1}"] = q[order, j] if len(order) else np.zeros(0)
    return table
