"""Which side of the loop each effect lives on: the robot's or the sensor's (the one map of it).

An effect on the robot's side is the arm's own (its zero-offsets, link geometry, compliance, joint
scales, a drift of its joints): a calibration of the arm carries it to other cells. One on the
sensor's side belongs to the measuring set-up: its registration, its scale and frame distortion,
its noise, and the marker it sights on the flange (each sensor its own, not the arm's tool). The
residual GP models a base-frame residual: it is not attributed. loop_closure.json records the
side of each effect added (`effects_sides`) and the tables and certificate name it beside the
effect: "joint_compliance (robot), sensor_distortion (sensor)".
"""

from __future__ import annotations

from collections.abc import Iterable

ROBOT, SENSOR, UNATTRIBUTED = "robot", "sensor", "unattributed"
SIDES = {
    "registration": SENSOR,
    "zero_offsets": ROBOT,
    "joint_compliance": ROBOT,
    "joint_scale": ROBOT,
    "marker_offset": SENSOR,
    "sensor_scale": SENSOR,
    "link_geometry": ROBOT,
    "drift": ROBOT,
    "sensor_distortion": SENSOR,
    "joint_harmonics": ROBOT,
    "noise": SENSOR,
    "residual_gp": UNATTRIBUTED,
}


def side_of(effect: str) -> str:
    """'robot', 'sensor' or 'unattributed' for a block or candidate name; a name the map lacks (a
    candidate added since) is 'unattributed' rather than guessed."""
    return SIDES.get(effect, UNATTRIBUTED)


def sides_of(effects: Iterable[str]) -> dict[str, str]:
    """{effect: side} in the order given."""
    return {e: side_of(e) for e in effects}


def with_sides(effects: Iterable[str], empty: str = "none") -> str:
    """'joint_compliance (robot), sensor_distortion (sensor)'; `empty` when there are none."""
    return ", ".join(f"{e} ({side_of(e)})" for e in effects) or empty
