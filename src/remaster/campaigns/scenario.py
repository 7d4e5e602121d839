"""Simulated campaigns from a scenario (a YAML mapping): plan, measure, and keep the truth apart.

A scenario names the robot, how to plan the poses, the true robot (zero-offsets and effects)
and the sensors. `simulate` turns it into the contract's campaign metadata and sensor tables
plus a ground-truth record; everything random comes from one Generator seeded by the scenario.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import InputError
from ..robot import planning, registration
from ..robot.kinematics import ForwardKinematics, KinematicChain
from ..units import SECONDS_PER_HOUR
from .simulation import Sensor, TrueRobot, looking_at, measure, true_marker_positions


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
        raise InputError(f"expected {n} numbers, got {value!r}", key=f"{where}/{key}")
    return array * scale


def true_robot(spec: dict, n_joints: int, rng: np.random.Generator) -> TrueRobot:
    """The true robot of a scenario's `truth` block; random link errors are drawn from rng."""
    truth = spec.get("truth", {})
    offsets = _vector(truth, "zero_offsets_deg", n_joints, np.pi / 180.0)
    if offsets is None:
        raise InputError("a scenario needs the true zero-offsets", key="truth/zero_offsets_deg")
    link_errors = None
    if truth.get("link_errors"):
        sizes = truth["link_errors"]
        # a seed of their own keeps one robot's links the same across its campaigns
        draw = np.random.default_rng(sizes["seed"]) if "seed" in sizes else rng
        link_errors = np.column_stack(
            [
                draw.normal(0.0, float(sizes["length_std"]), n_joints + 1),
                draw.normal(0.0, float(sizes["twist_std"]), n_joints + 1),
            ]
        )
    payload = truth.get("payload") or {}
    drift = _vector(truth, "drift_deg_per_hour", n_joints, np.pi / 180.0 / SECONDS_PER_HOUR)
    cyclic = None
    if truth.get("cyclic_error"):
        spec_c = truth["cyclic_error"]
        where = "truth/cyclic_error"
        cyclic = np.column_stack(
            [
                _vector(spec_c, "amplitude_deg", n_joints, np.pi / 180.0, where),
                _vector(spec_c, "cycles_per_turn", n_joints, 1.0, where),
                _vector(spec_c, "phase_deg", n_joints, np.pi / 180.0, where),
            ]
        )
    return TrueRobot(
        zero_offsets=offsets,
        joint_compliance=_vector(truth, "joint_compliance", n_joints),
        payload_mass=float(payload.get("mass", 0.0)),
        payload_com=np.asarray(payload.get("com", [0, 0, 0]), float),
        link_errors=link_errors,
        joint_scale=_vector(truth, "joint_scale", n_joints),
        drift_rate=drift,
        cyclic_error=cyclic,
    )


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
        )
    return out


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


def copies(spec: dict, count: int | None, seed: int | None = None):
    """(scenario, seed) pairs: the scenario itself, or `count` copies named <name>-001, ... with
    consecutive seeds from `seed` (default the scenario's), for a simulated fleet."""
    first = spec["seed"] if seed is None else seed
    if count is None:
        return [(spec, first)]
    return [({**spec, "name": f"{spec['name']}-{i + 1:03d}"}, first + i) for i in range(count)]


def simulate(spec: dict, chain: KinematicChain, seed: int | None = None) -> SimulatedCampaign:
    """Plan, measure and record one scenario. `seed` overrides the scenario's own."""
    rng = np.random.default_rng(spec["seed"] if seed is None else seed)
    robot = true_robot(spec, chain.n_joints, rng)
    sensors = sensors_of(spec)
    plan_spec = spec["plan"]
    reference = sensors[plan_spec["reference_sensor"]]
    target = estimated_sensor_origin(chain, robot, reference, rng)
    collision = planning.CollisionModel(**plan_spec.get("collision", {}))
    sights = [planning.SightLine(s.pose_in_robot[:3, 3], s.marker) for s in sensors.values()]
    design = plan_spec.get("design", LATIN_HYPERCUBE)
    if design not in (LATIN_HYPERCUBE, ISO9283_CUBES):
        raise InputError(f"unknown design {design!r} (known: {LATIN_HYPERCUBE}, {ISO9283_CUBES})", key="plan/design")
    q3 = float(plan_spec.get("q3", 0.0))
    if design == ISO9283_CUBES:
        cubes = {set_name: _cubes(size, f"plan/sets/{set_name}") for set_name, size in plan_spec["sets"].items()}
        rotation = planning.cube_orientation(
            [centre for each in cubes.values() for centre, _ in each], target, float(plan_spec.get("tool_angle", 0.0))
        )
    tables = []
    discarded = {}
    for set_name, size in plan_spec["sets"].items():
        if design == ISO9283_CUBES:
            plan = planning.plan_cubes(chain, set_name, cubes[set_name], rotation, sights, model=collision, q3=q3)
        else:
            plan = planning.plan_set(
                chain,
                set_name,
                target,
                sights,
                rng,
                candidates=int(plan_spec["candidates"]),
                n_poses=size.get("poses"),
                n_configurations=size.get("configurations"),
                model=collision,
                q3=q3,
            )
        tables.append(plan.table)
        discarded[set_name] = {"candidate_poses": plan.candidates, **plan.discarded}
    readings = pd.concat(tables, ignore_index=True)
    q = readings[[f"q{j + 1}" for j in range(chain.n_joints)]].to_numpy()
    elapsed = np.arange(len(readings)) * float(plan_spec["seconds_per_configuration"])
    start = pd.Timestamp(spec["date"], tz="UTC") + pd.Timedelta(hours=9)
    times = start + pd.to_timedelta(elapsed, unit="s")

    out_tables, truth_sensors = {}, {}
    for name, sensor in sensors.items():
        xyz = measure(chain, robot, sensor, q, rng, elapsed)
        unseen = rng.choice(len(xyz), size=int(spec["sensors"][name].get("missing", 0)), replace=False)
        xyz[np.sort(unseen)] = np.nan
        table = readings.copy()
        table[["x", "y", "z"]] = xyz
        table["time"] = times
        out_tables[name] = table
        truth_sensors[name] = {
            "kind": sensor.kind,
            "noise_m": sensor.noise,
            "scale_error": sensor.scale_error,
            **({"transverse_growth_per_m": sensor.transverse_growth_per_m} if sensor.transverse_growth_per_m else {}),
            "marker_error_m": sensor.marker_error.tolist(),
            "T_NR": sensor.robot_to_sensor.tolist(),
            "pose_in_robot": sensor.pose_in_robot.tolist(),
            "unseen_rows": sorted(int(i) for i in unseen),
            "true_marker_positions_robot_frame_m": true_marker_positions(chain, robot, sensor, q, elapsed).tolist(),
        }
    metadata = {
        "name": spec["name"],
        "date": str(spec["date"]),
        "description": spec.get("description", ""),
        "robot": dict(spec["robot"]),
        "sensors": {
            name: {"kind": s.kind, "marker": s.marker.tolist(), "noise": s.noise} for name, s in sensors.items()
        },
    }
    truth = {
        "campaign": spec["name"],
        "seed": int(spec["seed"] if seed is None else seed),
        "zero_offsets_deg": np.degrees(robot.zero_offsets).tolist(),
        "effects": _effects_record(robot),
        "sensors": truth_sensors,
        "planning": {"estimated_reference_sensor_origin_m": target.tolist(), "discarded": discarded},
    }
    if design == ISO9283_CUBES:
        # the Latin-hypercube truth files stay as they were; a cube campaign records its one orientation
        truth["planning"].update(design=design, flange_rotation=rotation.tolist())
    return SimulatedCampaign(metadata, out_tables, truth)


def robot_from_truth(truth: dict) -> TrueRobot:
    """The true robot of a ground-truth record (data/truth/<campaign>.json, as `simulate` writes
    it): the inverse of its `zero_offsets_deg` and `effects`."""
    effects = truth.get("effects", {})
    compliance, links = effects.get("joint_compliance"), effects.get("link_geometry")
    cyclic, drift = effects.get("cyclic_error"), effects.get("drift")
    return TrueRobot(
        zero_offsets=np.radians(truth["zero_offsets_deg"]),
        joint_compliance=np.array(compliance["compliance_rad_per_Nm"]) if compliance else None,
        payload_mass=float(compliance["payload_mass_kg"]) if compliance else 0.0,
        payload_com=np.array(compliance["payload_com_m"]) if compliance else np.zeros(3),
        link_errors=np.column_stack([links["length_errors_m"], links["twist_errors_rad"]]) if links else None,
        joint_scale=np.array(effects["joint_scale"]["scale"]) if "joint_scale" in effects else None,
        drift_rate=np.radians(drift["zero_offset_rate_deg_per_hour"]) / SECONDS_PER_HOUR if drift else None,
        cyclic_error=np.column_stack(
            [np.radians(cyclic["amplitude_deg"]), cyclic["cycles_per_turn"], np.radians(cyclic["phase_deg"])]
        )
        if cyclic
        else None,
    )


def sensor_from_truth(truth: dict, name: str, marker) -> Sensor:
    """The true sensor `name` of a ground-truth record, with the campaign's nominal marker (3,) m."""
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
    if robot.link_errors is not None:
        effects["link_geometry"] = {
            "length_errors_m": robot.link_errors[:, 0].tolist(),
            "twist_errors_rad": robot.link_errors[:, 1].tolist(),
            "links": "F_1 .. F_N, F_tool (the fixed transform before each joint, then the tool)",
        }
    if robot.joint_scale is not None:
        effects["joint_scale"] = {"scale": robot.joint_scale.tolist()}
    if robot.drift_rate is not None:
        effects["drift"] = {"zero_offset_rate_deg_per_hour": np.degrees(robot.drift_rate * SECONDS_PER_HOUR).tolist()}
    if robot.cyclic_error is not None:
        effects["cyclic_error"] = {
            "amplitude_deg": np.degrees(robot.cyclic_error[:, 0]).tolist(),
            "cycles_per_turn": robot.cyclic_error[:, 1].tolist(),
            "phase_deg": np.degrees(robot.cyclic_error[:, 2]).tolist(),
        }
    return effects
