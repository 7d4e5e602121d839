"""Simulated campaigns from a scenario (a YAML mapping): plan, measure, and keep the truth apart.

A scenario names the robot, how to plan the poses, the true robot (zero-offsets and effects)
and the sensors. `simulate` turns it into the contract's campaign metadata and sensor tables
plus a ground-truth record; everything random comes from one Generator seeded by the scenario.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import spatial
from ..errors import InputError, quoted
from ..robot import planning, registration
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..units import SECONDS_PER_HOUR
from .simulation import (
    DHErrors,
    Sensor,
    TrueRobot,
    frame_distortion,
    looking_at,
    measure,
    measure_orientations,
    same_frames_as_dh,
    sensor_move,
    sensor_side,
    true_marker_positions,
)


@dataclass(frozen=True)
class SimulatedCampaign:
    """metadata: campaign.yaml content; tables: one DataFrame per sensor; truth: ground truth."""

    metadata: dict
    tables: dict[str, pd.DataFrame]
    truth: dict


def _vector(mapping: dict, key: str, n: int, scale: float = 1.0, where: str = "truth") -> np.ndarray | None:
    value = mapping.get(key)
    if value is None:
        return None
    array = np.asarray(value, dtype=float)
    if array.shape != (n,):
        raise InputError(f"expected {n} numbers, got {quoted(value)}", key=f"{where}/{key}")
    return array * scale


def _std(mapping: dict, key: str, where: str) -> float:
    value = mapping.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
        raise InputError(f"needs a standard deviation >= 0, got {quoted(value)}", key=f"{where}/{key}")
    return float(value)


def _own_draw(sizes: dict, where: str, rng: np.random.Generator) -> np.random.Generator:
    """The generator of an effect's random parameters: its own seed's when it has one, so that one
    robot's links stay the same across its campaigns, else the scenario's."""
    if "seed" not in sizes:
        return rng
    seed = sizes["seed"]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"must be an integer >= 0, got {quoted(seed)}", key=f"{where}/seed")
    return np.random.default_rng(seed)


def _checked_keys(mapping, known: tuple[str, ...], where: str, hint: str = "") -> dict:
    if not isinstance(mapping, dict):
        raise InputError(f"must be a mapping with keys {', '.join(known)}, got {quoted(mapping)}", key=where)
    unknown = [k for k in mapping if k not in known]
    if unknown:
        raise InputError(f"unknown key (known: {', '.join(known)}){hint}", key=f"{where}/{unknown[0]}")
    return mapping


LINK_MOTION_KEYS = ("translation_std", "rotation_std", "seed")  # m, rad
DH_ERROR_KEYS = ("std", "seed")  # std: [a (m), alpha (rad), d (m), theta (rad)]
TRUTH_KEYS = (
    "zero_offsets_deg",
    "joint_compliance",
    "payload",
    "link_errors",
    "dh_errors",
    "joint_scale",
    "drift_deg_per_hour",
    "cyclic_error",
    "backlash_deg",
    "link_scale",
)


def _link_truth(sizes, n_joints: int, rng: np.random.Generator) -> np.ndarray:
    """Rigid link motions (N + 1, 6) of `truth/link_errors` (`simulation.moved_transforms`)."""
    where = "truth/link_errors"
    _checked_keys(sizes, LINK_MOTION_KEYS, where)
    draw = _own_draw(sizes, where, rng)
    count = n_joints + 1  # F_1 .. F_N, F_tool
    translation, rotation = _std(sizes, "translation_std", where), _std(sizes, "rotation_std", where)
    return np.hstack([draw.normal(0.0, translation, (count, 3)), draw.normal(0.0, rotation, (count, 3))])


def _dh_truth(sizes, robot_spec: dict, n_joints: int, rng: np.random.Generator) -> DHErrors:
    """The true DH table of `truth/dh_errors` for a robot given by a DH table."""
    where = "truth/dh_errors"
    _checked_keys(sizes, DH_ERROR_KEYS, where)
    dh = robot_spec.get("dh") if isinstance(robot_spec, dict) else None
    if not isinstance(dh, dict) or "rows" not in dh:
        raise InputError("DH errors need a robot given by a DH table (robot/dh)", key=where)
    rows = np.asarray(dh["rows"], dtype=float)
    if rows.shape != (n_joints, 4):
        raise InputError(f"robot/dh/rows must be {n_joints} rows of [a, alpha, d, theta]", key=where)
    std = _vector(sizes, "std", 4, where=where)
    if std is None or not np.all(std >= 0):
        raise InputError("needs std: [a (m), alpha (rad), d (m), theta (rad)], each >= 0", key=f"{where}/std")
    errors = _own_draw(sizes, where, rng).normal(0.0, std, (n_joints, 4))
    flange = np.eye(4) if dh.get("flange") is None else np.asarray(dh["flange"], dtype=float)
    return DHErrors(rows, errors, str(dh.get("convention", "standard")), flange)


def true_robot(spec: dict, n_joints: int, rng: np.random.Generator) -> TrueRobot:
    """The true robot of a scenario's `truth` block; random link and DH errors are drawn from
    their own seed when they have one, else from rng."""
    truth = _checked_keys(spec.get("truth", {}), TRUTH_KEYS, "truth")
    offsets = _vector(truth, "zero_offsets_deg", n_joints, np.pi / 180.0)
    if offsets is None:
        raise InputError("a scenario needs the true zero-offsets", key="truth/zero_offsets_deg")
    link_motions = _link_truth(truth["link_errors"], n_joints, rng) if truth.get("link_errors") else None
    dh_errors = _dh_truth(truth["dh_errors"], spec.get("robot"), n_joints, rng) if truth.get("dh_errors") else None
    payload = truth.get("payload") or {}
    drift = _vector(truth, "drift_deg_per_hour", n_joints, np.pi / 180.0 / SECONDS_PER_HOUR)
    cyclic = None
    if truth.get("cyclic_error"):
        # one term {amplitude_deg, cycles_per_turn, phase_deg} per joint, or a list of such terms (summed)
        terms = truth["cyclic_error"]
        terms = terms if isinstance(terms, list) else [terms]
        stack = []
        for i, spec_c in enumerate(terms):
            where = "truth/cyclic_error" if len(terms) == 1 else f"truth/cyclic_error/{i}"
            stack.append(
                np.column_stack(
                    [
                        _vector(spec_c, "amplitude_deg", n_joints, np.pi / 180.0, where),
                        _vector(spec_c, "cycles_per_turn", n_joints, 1.0, where),
                        _vector(spec_c, "phase_deg", n_joints, np.pi / 180.0, where),
                    ]
                )
            )
        cyclic = stack[0] if len(stack) == 1 else np.stack(stack)
    return TrueRobot(
        zero_offsets=offsets,
        joint_compliance=_vector(truth, "joint_compliance", n_joints),
        payload_mass=float(payload.get("mass", 0.0)),
        payload_com=np.asarray(payload.get("com", [0, 0, 0]), float),
        joint_scale=_vector(truth, "joint_scale", n_joints),
        drift_rate=drift,
        cyclic_error=cyclic,
        link_motions=link_motions,
        dh_errors=dh_errors,
        backlash=_vector(truth, "backlash_deg", n_joints, np.pi / 180.0),
        link_scale=_link_scale(truth),
    )


def _link_scale(truth: dict) -> float:
    """`truth/link_scale`: every link's length grown by this factor (thermal growth), 1."""
    value = truth.get("link_scale", 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not abs(value) < 0.1:
        raise InputError(f"must be a small factor (|s| < 0.1), got {quoted(value)}", key="truth/link_scale")
    return float(value)


def sensors_of(spec: dict) -> dict[str, Sensor]:
    """The scenario's sensors, in the order given."""
    out = {}
    for name, s in spec["sensors"].items():
        out[name] = Sensor(
            name=name,
            kind=s["kind"],
            pose_in_robot=looking_at(s["position"], s["look_at"]),
            noise=float(s["noise"]),
            marker=np.asarray(s["marker"], dtype=float),
            marker_error=np.asarray(s.get("marker_error", [0.0, 0.0, 0.0]), dtype=float),
            scale_error=float(s.get("scale_error", 0.0)),
            transverse_growth_per_m=float(s.get("transverse_growth_per_m", 0.0)),
            orientation_noise=float(s.get("orientation_noise", 0.0)),
            probe_rotation=spatial.rotation_vector_to_matrix(np.asarray(s.get("probe_rotation", [0.0] * 3), float)),
            probe_rotation_error=np.asarray(s.get("probe_rotation_error", [0.0] * 3), dtype=float),
        )
    return out


MOVE_KEYS = ("translation_m", "rotation_deg")
DISTORTION_KEYS = ("scale", "shear")


def sensor_side_of(sensor_spec: dict, where: str) -> tuple[np.ndarray | None, np.ndarray | None, dict]:
    """(move (4, 4) or None, distortion (3, 3) or None, the truth's record of them) of one sensor's
    scenario keys `moved_between_sets` {translation_m: [x, y, z] (m), rotation_deg: [rx, ry, rz]}
    (the validation set's readings moved, `simulation.sensor_move`) and `frame_distortion`
    {scale: [sx, sy, sz], shear: [xy, xz, yz]} (every reading, `simulation.frame_distortion`)."""
    move = distortion = None
    record = {}
    if sensor_spec.get("moved_between_sets"):
        key = f"{where}/moved_between_sets"
        spec = _checked_keys(sensor_spec["moved_between_sets"], MOVE_KEYS, key)
        translation = _vector(spec, "translation_m", 3, where=key)
        rotation = _vector(spec, "rotation_deg", 3, np.pi / 180.0, where=key)
        translation = np.zeros(3) if translation is None else translation
        rotation = np.zeros(3) if rotation is None else rotation
        move = sensor_move(translation, rotation)
        record["moved_between_sets"] = {
            "translation_m": translation.tolist(),
            "rotation_deg": np.degrees(rotation).tolist(),
            "transform": move.tolist(),
            "applied_to": "validation",
            "convention": "m' = R m + t in the sensor frame, R = Rz(rz) Ry(ry) Rx(rx)",
        }
    if sensor_spec.get("frame_distortion"):
        key = f"{where}/frame_distortion"
        spec = _checked_keys(sensor_spec["frame_distortion"], DISTORTION_KEYS, key)
        scale = _vector(spec, "scale", 3, where=key)
        shear = _vector(spec, "shear", 3, where=key)
        distortion = frame_distortion(np.zeros(3) if scale is None else scale, np.zeros(3) if shear is None else shear)
        record["frame_distortion"] = {
            "scale": [] if scale is None else scale.tolist(),
            "shear_xy_xz_yz": [] if shear is None else shear.tolist(),
            "matrix": distortion.tolist(),
            "convention": "m' = (I + D) m about the sensor frame's origin, every reading",
        }
    return move, distortion, record


# Three configurations spread over the workspace, marker towards +x, for the paper's initial
# three-point registration of the reference sensor (rad).
REGISTRATION_CONFIGURATIONS = np.radians(
    [
        [-40.0, 40.0, 0.0, -70.0, 0.0, 50.0, 0.0],
        [0.0, 20.0, 0.0, -100.0, 0.0, -30.0, 0.0],
        [40.0, 55.0, 0.0, -40.0, 0.0, 60.0, 0.0],
    ]
)


def estimated_sensor_origin(
    chain: KinematicChain, robot: TrueRobot, sensor: Sensor, rng: np.random.Generator
) -> np.ndarray:
    """The reference sensor's origin in the robot frame as the paper finds it: three
    configurations measured by the sensor and computed by nominal forward kinematics, registered
    by the three-point method (so it carries the robot's and the sensor's errors)."""
    q = REGISTRATION_CONFIGURATIONS[:, : chain.n_joints]
    nominal = ForwardKinematics(chain, q).points(sensor.marker)
    measured = measure(chain, robot, sensor, q, rng, elapsed_s=np.zeros(len(q)))
    t_nr = registration.three_point(nominal, measured)
    return np.linalg.inv(t_nr)[:3, 3]


LATIN_HYPERCUBE = "latin_hypercube"  # the paper's design, the default
ISO9283_CUBES = "iso9283_cubes"
RANDOM_JOINTS = "random_joints"  # joint-space draws: any joint held, any arm (no inverse kinematics)
DESIGNS = (LATIN_HYPERCUBE, ISO9283_CUBES, RANDOM_JOINTS)
PLAN_KEYS = (
    "design",
    "reference_sensor",
    "candidates",
    "q3",
    "held_joints",
    "joint_ranges",
    "tool_angle",
    "collision",
    "seconds_per_configuration",
    "sets",
)
SET_KEYS = {LATIN_HYPERCUBE: ("poses", "configurations"), ISO9283_CUBES: ("cubes",), RANDOM_JOINTS: ("configurations",)}
RANDOM_CANDIDATES = 200  # configurations per batch of the random_joints design unless plan/candidates says


@dataclass(frozen=True)
class Holding:
    """Which joints a scenario's campaign holds. q3: joint 3's angle (rad) for the inverse-kinematics
    designs, or planning.FREE (drawn for each pose); held: {joint (0-based): angle (rad)} of the
    random_joints design, every other joint moving."""

    q3: float | str
    held: dict[int, float]

    def record(self, design: str) -> dict:
        """The truth file's note of it (only for campaigns that do not hold joint 3 at a number
        the default way, so that earlier truth files stay as they were)."""
        held = {f"q{j + 1}": angle for j, angle in sorted(self.held.items())}
        if design != RANDOM_JOINTS:
            held = {"q3": self.q3} if self.q3 != planning.FREE else {}
        return {"design": design, "held_joints_rad": held}


def _angle(value, chain: KinematicChain, joint: int, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise InputError(f"must be an angle (rad) or {quoted(planning.FREE)}, got {quoted(value)}", key=key)
    if not chain.lower[joint] <= value <= chain.upper[joint]:
        raise InputError(
            f"{value:g} rad is outside joint {joint + 1}'s limits [{chain.lower[joint]:g}, {chain.upper[joint]:g}] rad",
            key=key,
        )
    return float(value)


def holding(plan_spec: dict, chain: KinematicChain, design: str) -> Holding:
    """The joints a scenario's `plan` holds: `q3` (an angle in rad, or 'free'; 0 by default for the
    inverse-kinematics designs, free for random_joints) and `held_joints` {q<j>: angle (rad)}. The
    inverse kinematics of the latin_hypercube and iso9283_cubes designs can hold joint 3 only."""
    spec = plan_spec.get("held_joints") or {}
    if not isinstance(spec, dict):
        raise InputError("must be a mapping {q<j>: angle (rad)}, e.g. {q1: 0.0, q7: 0.0}", key="plan/held_joints")
    held = {}
    for name, value in spec.items():
        key = f"plan/held_joints/{name}"
        match = re.fullmatch(r"q([1-9][0-9]*)", str(name))
        if match is None or int(match.group(1)) > chain.n_joints:
            raise InputError(f"names no joint of the robot (q1 .. q{chain.n_joints})", key=key)
        joint = int(match.group(1)) - 1
        held[joint] = _angle(value, chain, joint, key)
    q3 = plan_spec.get("q3")
    if q3 is not None and 2 in held:
        raise InputError("joint 3 is held twice, by plan/q3 and by plan/held_joints/q3: keep one", key="plan/q3")
    if q3 is not None and q3 != planning.FREE:
        q3 = held[2] = _angle(q3, chain, 2, "plan/q3")
    if design == RANDOM_JOINTS:
        return Holding(planning.FREE, held)
    if chain.n_joints != 7:
        raise InputError(
            f"the {design} design needs a 7-axis S-R-S arm's inverse kinematics; plan this "
            f"{chain.n_joints}-axis arm with design: {RANDOM_JOINTS}",
            key="plan/design",
        )
    others = [j for j in held if j != 2]
    if others:
        raise InputError(
            f"the {design} design's inverse kinematics holds joint 3 only; to hold joint {others[0] + 1} "
            f"plan with design: {RANDOM_JOINTS}",
            key=f"plan/held_joints/q{others[0] + 1}",
        )
    return Holding(held.get(2, planning.FREE if q3 == planning.FREE else 0.0), {})


def joint_ranges(plan_spec: dict, chain: KinematicChain, design: str) -> dict[int, tuple[float, float]]:
    """The region of joint space a random_joints plan draws from: `joint_ranges` {q<j>: [low, high]}
    (rad, within the joint's limits; a joint without limits, e.g. a DH table's, may be drawn a turn
    away); the other joints within their `planning.joint_range`."""
    spec = plan_spec.get("joint_ranges") or {}
    if spec and design != RANDOM_JOINTS:
        raise InputError(f"joint ranges are drawn by design: {RANDOM_JOINTS}", key="plan/joint_ranges")
    if not isinstance(spec, dict):
        raise InputError("must be a mapping {q<j>: [low, high] (rad)}", key="plan/joint_ranges")
    out = {}
    for name, value in spec.items():
        key = f"plan/joint_ranges/{name}"
        match = re.fullmatch(r"q([1-9][0-9]*)", str(name))
        if match is None or int(match.group(1)) > chain.n_joints:
            raise InputError(f"names no joint of the robot (q1 .. q{chain.n_joints})", key=key)
        joint = int(match.group(1)) - 1
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise InputError(f"must be [low, high] (rad), got {quoted(value)}", key=key)
        low, high = (_angle(v, chain, joint, key) for v in value)
        if not low < high:
            raise InputError(f"needs low < high, got {quoted(value)}", key=key)
        out[joint] = (low, high)
    return out


def _sets(plan_spec: dict, design: str) -> dict:
    sets = plan_spec.get("sets")
    if not isinstance(sets, dict) or not sets:
        raise InputError("a plan needs its sets, e.g. {optimization: ..., validation: ...}", key="plan/sets")
    for name, size in sets.items():
        _checked_keys(size, SET_KEYS[design], f"plan/sets/{name}", f" for design {design}")
    return sets


def _cubes(size: dict, where: str) -> list[tuple[np.ndarray, float]]:
    """The (centre (3,) m, edge m) pairs of one set of a cube design."""
    cubes = size.get("cubes")
    if not cubes or not isinstance(cubes, list):
        raise InputError("a set of the iso9283_cubes design needs a list of cubes", key=f"{where}/cubes")
    out = []
    for i, cube in enumerate(cubes):
        key = f"{where}/cubes/{i}"
        if not isinstance(cube, dict):
            raise InputError("a cube is a mapping {centre: [x, y, z], edge: e} (m)", key=key)
        centre = _vector(cube, "centre", 3, where=key)
        edge = cube.get("edge")
        if centre is None or not isinstance(edge, (int, float)) or not edge > 0:
            raise InputError("a cube needs a centre (3 numbers, m) and an edge > 0 (m)", key=key)
        out.append((centre, float(edge)))
    return out


GROSS_ERROR_KEYS = ("optimization", "validation", "size_mm")


def inject_gross_errors(xyz, sets, spec, rng: np.random.Generator, where: str) -> tuple[np.ndarray, dict]:
    """Gross errors of a sensor, independent of any fit: `spec` {optimization: count, validation:
    count, size_mm: [low, high]} puts that many glitches on distinct measured rows of each set
    (rows drawn uniformly), each a displacement of a size uniform in [low, high] mm in a uniformly
    random direction. xyz (n, 3) m measured positions (NaN: not seen), sets (n,) each row's set.
    Returns the new positions and the truth file's record: {'rows': {set: [rows]}, 'size_mm',
    'glitches': [{'row', 'set', 'displacement_m'}]}."""
    spec = _checked_keys(spec, GROSS_ERROR_KEYS, f"{where}/gross_errors")
    size = spec.get("size_mm", [2.0, 5.0])
    if (
        not isinstance(size, (list, tuple))
        or len(size) != 2
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in size)
        or not 0 < size[0] <= size[1]
    ):
        raise InputError(
            f"needs [low, high] mm with 0 < low <= high, got {quoted(size)}", key=f"{where}/gross_errors/size_mm"
        )
    xyz = np.array(xyz, dtype=float)
    sets = np.asarray(sets)
    rows, glitches = {}, []
    for set_name in ("optimization", "validation"):
        count = spec.get(set_name, 0)
        measured = np.flatnonzero((sets == set_name) & np.all(np.isfinite(xyz), axis=1))
        if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= len(measured):
            raise InputError(
                f"needs a whole number of rows from 0 to the set's {len(measured)} measured rows, got {quoted(count)}",
                key=f"{where}/gross_errors/{set_name}",
            )
        chosen = np.sort(rng.choice(measured, size=count, replace=False))
        direction = rng.normal(size=(count, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        displacement = direction * rng.uniform(size[0], size[1], (count, 1)) * 1e-3
        xyz[chosen] += displacement
        rows[set_name] = chosen.tolist()
        glitches += [
            {"row": int(r), "set": set_name, "displacement_m": d.tolist()} for r, d in zip(chosen, displacement)
        ]
    return xyz, {"rows": rows, "size_mm": [float(v) for v in size], "glitches": glitches}


def copies(spec: dict, count: int | None, seed: int | None = None):
    """(scenario, seed) pairs: the scenario itself, or `count` copies named <name>-001, ... with
    consecutive seeds from `seed` (default the scenario's), for a simulated fleet."""
    first = spec["seed"] if seed is None else seed
    if count is None:
        return [(spec, first)]
    return [({**spec, "name": f"{spec['name']}-{i + 1:03d}"}, first + i) for i in range(count)]


def _plan(plan_spec: dict, design: str, chain: KinematicChain, robot: TrueRobot, sensors, held: Holding, rng):
    """(the readings' table: set, pose, solution, q1..qN rad; {set: what was drawn and discarded};
    the reference sensor's estimated origin (3,) m, None for random joint-space configurations; the
    cube design's flange rotation (3, 3), None for the others) of the scenario's `plan`."""
    sets = _sets(plan_spec, design)
    ranges = joint_ranges(plan_spec, chain, design)
    collision = planning.CollisionModel(**plan_spec.get("collision", {}))
    sights = [planning.SightLine(s.pose_in_robot[:3, 3], s.marker) for s in sensors.values()]
    target = rotation = None
    if design != RANDOM_JOINTS:  # the inverse-kinematics designs point the tool at the reference sensor
        if plan_spec.get("reference_sensor") not in sensors:
            raise InputError(f"must name one of the sensors ({', '.join(sensors)})", key="plan/reference_sensor")
        target = estimated_sensor_origin(chain, robot, sensors[plan_spec["reference_sensor"]], rng)
    if design == ISO9283_CUBES:
        cubes = {set_name: _cubes(size, f"plan/sets/{set_name}") for set_name, size in sets.items()}
        rotation = planning.cube_orientation(
            [centre for each in cubes.values() for centre, _ in each], target, float(plan_spec.get("tool_angle", 0.0))
        )
    tables = []
    discarded = {}
    for set_name, size in sets.items():
        if design == ISO9283_CUBES:
            plan = planning.plan_cubes(
                chain, set_name, cubes[set_name], rotation, sights, model=collision, q3=held.q3, rng=rng
            )
        elif design == RANDOM_JOINTS:
            count = size.get("configurations")
            if isinstance(count, bool) or not isinstance(count, int) or count < 1:
                raise InputError(
                    f"must be a whole number > 0, got {quoted(count)}", key=f"plan/sets/{set_name}/configurations"
                )
            plan = planning.plan_random(
                chain,
                set_name,
                sights,
                rng,
                n_configurations=count,
                held={**held.held, **ranges},
                candidates=int(plan_spec.get("candidates", RANDOM_CANDIDATES)),
                model=collision,
            )
        else:
            plan = planning.plan_set(
                chain,
                set_name,
                target,
                sights,
                rng,
                size=planning.SetSize(int(plan_spec["candidates"]), size.get("poses"), size.get("configurations")),
                model=collision,
                q3=held.q3,
            )
        tables.append(plan.table)
        drawn = "candidate_configurations" if design == RANDOM_JOINTS else "candidate_poses"
        discarded[set_name] = {drawn: plan.candidates, **plan.discarded}
    return pd.concat(tables, ignore_index=True), discarded, target, rotation


def _measured(name: str, spec: dict, sensor: Sensor, chain, robot: TrueRobot, readings, elapsed, rng):
    """(columns {x, y, z (m) and, for a full-pose probe, rx, ry, rz (rad)}, the truth's record) of
    one sensor measuring the readings' configurations at `elapsed` (n,) s: its noise, what happens
    to it (`sensor_side`), the rows it does not see (NaN) and its glitches, as the scenario's
    `sensors/<name>` (`spec`) says."""
    q = readings[[f"q{j + 1}" for j in range(chain.n_joints)]].to_numpy()
    xyz = measure(chain, robot, sensor, q, rng, elapsed)
    move, distortion, sensor_record = sensor_side_of(spec, f"sensors/{name}")
    xyz = sensor_side(xyz, readings["set"].to_numpy() == "validation", move, distortion)
    unseen = rng.choice(len(xyz), size=int(spec.get("missing", 0)), replace=False)
    xyz[np.sort(unseen)] = np.nan
    glitches = spec.get("gross_errors")
    if glitches is not None:
        xyz, glitched = inject_gross_errors(xyz, readings["set"].to_numpy(), glitches, rng, f"sensors/{name}")
    columns = dict(zip(("x", "y", "z"), xyz.T))
    if sensor.orientation_noise > 0:
        orientation = measure_orientations(chain, robot, sensor, q, rng, elapsed)
        if move is not None:  # a bumped sensor sees the probe turned too (a distortion leaves rotations alone)
            moved = readings["set"].to_numpy() == "validation"
            turned = move[:3, :3] @ spatial.rotation_vector_to_matrix(orientation[moved])
            orientation[moved] = spatial.matrix_to_rotation_vector(turned)
        orientation[np.sort(unseen)] = np.nan
        columns |= dict(zip(("rx", "ry", "rz"), orientation.T))
    return columns, {
        "kind": sensor.kind,
        "noise_m": sensor.noise,
        "scale_error": sensor.scale_error,
        **({"transverse_growth_per_m": sensor.transverse_growth_per_m} if sensor.transverse_growth_per_m else {}),
        "marker_error_m": sensor.marker_error.tolist(),
        **(
            {
                "orientation_noise_rad": sensor.orientation_noise,
                "probe_rotation_error_rad": sensor.probe_rotation_error.tolist(),
            }
            if sensor.orientation_noise > 0
            else {}
        ),
        "T_NR": sensor.robot_to_sensor.tolist(),
        "pose_in_robot": sensor.pose_in_robot.tolist(),
        "unseen_rows": sorted(int(i) for i in unseen),
        **({"gross_errors": glitched} if glitches is not None else {}),
        "true_marker_positions_robot_frame_m": true_marker_positions(chain, robot, sensor, q, elapsed).tolist(),
        **sensor_record,
    }


def simulate(spec: dict, chain: KinematicChain, seed: int | None = None) -> SimulatedCampaign:
    """Plan, measure and record one scenario. `seed` overrides the scenario's own."""
    rng = np.random.default_rng(spec["seed"] if seed is None else seed)
    robot = true_robot(spec, chain.n_joints, rng)
    if robot.dh_errors is not None and robot.joint_compliance is not None and chain.inertias is not None:
        if not same_frames_as_dh(chain, robot.dh_errors):
            raise InputError(
                "DH errors rebuild the joint frames from the DH table, and the URDF's mass data are in "
                "other frames: simulate joint compliance and DH errors in separate scenarios",
                key="truth/dh_errors",
            )
    sensors = sensors_of(spec)
    plan_spec = _checked_keys(spec.get("plan"), PLAN_KEYS, "plan")
    design = plan_spec.get("design", LATIN_HYPERCUBE)
    if design not in DESIGNS:
        raise InputError(f"unknown design {quoted(design)} (known: {', '.join(DESIGNS)})", key="plan/design")
    held = holding(plan_spec, chain, design)
    readings, discarded, target, rotation = _plan(plan_spec, design, chain, robot, sensors, held, rng)
    elapsed = np.arange(len(readings)) * float(plan_spec["seconds_per_configuration"])
    start = pd.Timestamp(spec["date"], tz="UTC") + pd.Timedelta(hours=9)
    times = start + pd.to_timedelta(elapsed, unit="s")

    out_tables, truth_sensors = {}, {}
    for name, sensor in sensors.items():
        columns, truth_sensors[name] = _measured(
            name, spec["sensors"][name], sensor, chain, robot, readings, elapsed, rng
        )
        table = readings.copy()
        for column, values in columns.items():
            table[column] = values
        table["time"] = times
        out_tables[name] = table
    metadata = {
        "name": spec["name"],
        "date": str(spec["date"]),
        "description": spec.get("description", ""),
        "robot": dict(spec["robot"]),
        "sensors": {name: _sensor_metadata(s) for name, s in sensors.items()},
    }
    truth = {
        "campaign": spec["name"],
        "seed": int(spec["seed"] if seed is None else seed),
        "zero_offsets_deg": np.degrees(robot.zero_offsets).tolist(),
        "effects": _effects_record(robot),
        "sensors": truth_sensors,
        "planning": {"discarded": discarded},
    }
    if target is not None:  # first, as truth files have always had it
        truth["planning"] = {"estimated_reference_sensor_origin_m": target.tolist(), **truth["planning"]}
    if design == RANDOM_JOINTS or held.q3 == planning.FREE or "held_joints" in plan_spec:
        truth["planning"].update(held.record(design))
    if design == ISO9283_CUBES:
        # the Latin-hypercube truth files stay as they were; a cube campaign records its one orientation
        truth["planning"].update(design=design, flange_rotation=rotation.tolist())
    return SimulatedCampaign(metadata, out_tables, truth)


def _sensor_metadata(sensor: Sensor) -> dict:
    """campaign.yaml's entry of a simulated sensor: a full-pose probe's orientation noise and
    nominal mounting besides the marker and noise."""
    out = {"kind": sensor.kind, "marker": sensor.marker.tolist(), "noise": sensor.noise}
    if sensor.orientation_noise > 0:
        out["orientation_noise"] = sensor.orientation_noise
        out["probe_rotation"] = spatial.matrix_to_rotation_vector(sensor.probe_rotation).tolist()
    return out


def robot_from_truth(truth: dict) -> TrueRobot:
    """The true robot of a ground-truth record (data/truth/<campaign>.json, as `simulate` writes
    it): the inverse of its `zero_offsets_deg` and `effects`."""
    effects = truth.get("effects", {})
    compliance = effects.get("joint_compliance")
    cyclic, drift = effects.get("cyclic_error"), effects.get("drift")
    motions, dh = effects.get("link_motions"), effects.get("dh_errors")
    return TrueRobot(
        zero_offsets=np.radians(truth["zero_offsets_deg"]),
        joint_compliance=np.array(compliance["compliance_rad_per_Nm"]) if compliance else None,
        payload_mass=float(compliance["payload_mass_kg"]) if compliance else 0.0,
        payload_com=np.array(compliance["payload_com_m"]) if compliance else np.zeros(3),
        joint_scale=np.array(effects["joint_scale"]["scale"]) if "joint_scale" in effects else None,
        drift_rate=np.radians(drift["zero_offset_rate_deg_per_hour"]) / SECONDS_PER_HOUR if drift else None,
        cyclic_error=_cyclic_terms(cyclic) if cyclic else None,
        link_motions=np.hstack([motions["translations_m"], motions["rotations_rpy_rad"]]) if motions else None,
        dh_errors=DHErrors(
            np.array(dh["nominal_rows"]), np.array(dh["errors"]), dh["convention"], np.array(dh["flange"])
        )
        if dh
        else None,
        backlash=np.radians(effects["backlash"]["half_play_deg"]) if "backlash" in effects else None,
        link_scale=float(effects.get("link_scale", {}).get("factor", 0.0)),
    )


def sensor_from_truth(truth: dict, name: str, marker, probe_rotation=None) -> Sensor:
    """The true sensor `name` of a ground-truth record, with the campaign's nominal marker (3,) m
    and, for a full-pose probe, its nominal mounting as a rotation vector (3,) rad."""
    record = truth["sensors"][name]
    return Sensor(
        name,
        record["kind"],
        np.array(record["pose_in_robot"]),
        float(record["noise_m"]),
        np.asarray(marker, dtype=float),
        np.array(record["marker_error_m"]),
        float(record["scale_error"]),
        float(record.get("transverse_growth_per_m", 0.0)),
        float(record.get("orientation_noise_rad", 0.0)),
        np.eye(3) if probe_rotation is None else spatial.rotation_vector_to_matrix(np.asarray(probe_rotation, float)),
        np.array(record.get("probe_rotation_error_rad", [0.0] * 3)),
    )


def _effects_record(robot: TrueRobot) -> dict:
    """Every effect beyond zero-offsets that the true robot has, with its parameters."""
    effects = {}
    if robot.joint_compliance is not None:
        effects["joint_compliance"] = {
            "compliance_rad_per_Nm": robot.joint_compliance.tolist(),
            "payload_mass_kg": robot.payload_mass,
            "payload_com_m": robot.payload_com.tolist(),
        }
    if robot.link_motions is not None:
        effects["link_motions"] = {
            "translations_m": robot.link_motions[:, :3].tolist(),
            "rotations_rpy_rad": robot.link_motions[:, 3:].tolist(),
            "transforms": "F_1 .. F_N, F_tool (the fixed transform before each joint, then the tool)",
            "convention": "F'_j = Trans(t_j) Rz(yaw_j) Ry(pitch_j) Rx(roll_j) F_j, rows [roll, pitch, yaw]: "
            "a motion in the frame F_j starts from",
        }
    if robot.dh_errors is not None:
        dh = robot.dh_errors
        effects["dh_errors"] = {
            "convention": dh.convention,
            "nominal_rows": np.asarray(dh.nominal_rows, dtype=float).tolist(),
            "errors": np.asarray(dh.errors, dtype=float).tolist(),
            "flange": np.asarray(dh.flange, dtype=float).tolist(),
            "columns": "a (m), alpha (rad), d (m), theta (rad); a theta error adds to the joint's zero-offset",
        }
    if robot.joint_scale is not None:
        effects["joint_scale"] = {"scale": robot.joint_scale.tolist()}
    if robot.backlash is not None:
        effects["backlash"] = {
            "half_play_deg": np.degrees(robot.backlash).tolist(),
            "convention": "+ half the play approached from below, - from above, in the readings' order",
        }
    if robot.link_scale:
        effects["link_scale"] = {"factor": robot.link_scale, "applies_to": "every fixed transform's translation"}
    if robot.drift_rate is not None:
        effects["drift"] = {"zero_offset_rate_deg_per_hour": np.degrees(robot.drift_rate * SECONDS_PER_HOUR).tolist()}
    if robot.cyclic_error is not None:
        terms = [
            {
                "amplitude_deg": np.degrees(term[:, 0]).tolist(),
                "cycles_per_turn": term[:, 1].tolist(),
                "phase_deg": np.degrees(term[:, 2]).tolist(),
            }
            for term in np.reshape(robot.cyclic_error, (-1,) + np.shape(robot.cyclic_error)[-2:])
        ]
        effects["cyclic_error"] = terms[0] if np.ndim(robot.cyclic_error) == 2 else terms
    return effects


def _cyclic_terms(record) -> np.ndarray:
    """(N, 3) or (T, N, 3) [amplitude (rad), cycles per turn, phase (rad)] of a truth record's
    cyclic error: one term or a list of terms."""
    terms = [
        np.column_stack([np.radians(t["amplitude_deg"]), t["cycles_per_turn"], np.radians(t["phase_deg"])])
        for t in (record if isinstance(record, list) else [record])
    ]
    return terms[0] if not isinstance(record, list) else np.stack(terms)
