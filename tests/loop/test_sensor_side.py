"""Sensor-side effects: the sensor frame's distortion block (`parameter_blocks.distortion_matrix`) against
hand-computed strains and the simulator's own distortion, a simulated anisotropic motion-capture
distortion attributed to the sensor by the loop closure (and not to compliance), and the one map
of which side each effect lives on (`remaster.loop.sides`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from remaster import spatial
from remaster.campaigns.arm_kinds import iiwa_scenario, simulated_sensor
from remaster.campaigns.simulation import Sensor, TrueRobot, frame_distortion, looking_at, measure, sensor_side
from remaster.inference import blocks
from remaster.inference.parameter_blocks import (
    BASE,
    DISTORTION_PARTS,
    EXTENSIONS,
    distortion_coefficients,
    distortion_matrix,
)
from remaster.inference.readings import Readings
from remaster.loop import sides
from remaster.robot.gravity import gravity_torques

from ..calibration.test_compensation import synthetic_robot
from ..conftest import REPO, loop_report, loop_settings

MOCAP_NOISE = 3.0e-5  # m per axis
MOCAP = {
    "kind": "motion_capture",
    "marker": [0.100, 0.0, 0.020],
    "noise": MOCAP_NOISE,
    "position": [1.6, 0.3, 1.6],
    "look_at": [0.0, 0.0, 0.6],
}
# the simulator's form: x' = (1 + 1.5e-3) x + 0.8e-3 y, y' = (1 - 1.0e-3) y, z' = z
DISTORTION = {"scale": [1.5e-3, -1.0e-3, 0.0], "shear": [0.8e-3, 0.0, 0.0]}
# its symmetric traceless part by hand: trace 0.5e-3, so S = diag(1.5, -1.0, 0) e-3 - 0.5e-3 / 3 I,
# S_xy = 0.8e-3 / 2; d1 = (S_xx - S_yy) / sqrt 2, d2 = (S_xx + S_yy - 2 S_zz) / sqrt 6
TRUE_STRAIN = {
    "sensor_distortion.d1": 2.5e-3 / math.sqrt(2.0),
    "sensor_distortion.d2": 0.5e-3 / math.sqrt(6.0),
    "sensor_distortion.xy": 0.4e-3,
    "sensor_distortion.xz": 0.0,
    "sensor_distortion.yz": 0.0,
}
TRUE_SCALE = 0.5e-3 / 3.0  # the isotropic part: sensor_scale's


def test_the_strain_coefficients_are_the_hand_computed_ones():
    error = frame_distortion(DISTORTION["scale"], DISTORTION["shear"]) - np.eye(3)
    found = distortion_coefficients(error)
    assert found == pytest.approx(TRUE_STRAIN, abs=1e-15)
    # back to the matrix: symmetric, traceless, the hand-computed entries
    strain = distortion_matrix([TRUE_STRAIN[f"sensor_distortion.{p}"] for p in DISTORTION_PARTS])
    expected = np.diag([1.5e-3, -1.0e-3, 0.0]) - TRUE_SCALE * np.eye(3)
    expected[0, 1] = expected[1, 0] = 0.4e-3
    np.testing.assert_allclose(strain, expected, atol=1e-15)
    # what the block leaves to others: a rotation (the registration's) and an isotropic scale
    rotation = np.array([[0.0, -1e-3, 2e-3], [1e-3, 0.0, -3e-3], [-2e-3, 3e-3, 0.0]])
    assert all(v == 0.0 for v in distortion_coefficients(rotation).values())
    assert all(abs(v) < 1e-18 for v in distortion_coefficients(4e-4 * np.eye(3)).values())


def test_the_block_with_the_true_strain_reproduces_the_simulators_distortion(iiwa, rng):
    """Noise-free readings through a symmetric traceless distortion in the simulator's own form
    (scales only: its shears are upper-triangular, never symmetric) are the block's prediction."""
    n, offsets = 30, np.radians([0.35, -0.21, 0.12, 0.18, -0.27, 0.09, 0.62])
    q = rng.uniform(np.maximum(iiwa.lower, -2.0), np.minimum(iiwa.upper, 2.0), (n, 7))
    sensor = Sensor("mc", "motion_capture", looking_at([1.6, 0.3, 1.6], [0, 0, 0.6]), 0.0, np.array([0.1, 0, 0.02]))
    distortion = frame_distortion([1.2e-3, -0.4e-3, -0.8e-3], [0.0, 0.0, 0.0])
    measured = sensor_side(measure(iiwa, TrueRobot(zero_offsets=offsets), sensor, q, rng), None, None, distortion)
    torques = gravity_torques(iiwa, q)
    data = Readings(np.arange(n), q, measured, torques, np.zeros_like(torques))
    model = blocks.BlockModel(iiwa, data, sensor.marker, sensor.robot_to_sensor, ["sensor_distortion"])
    values = {f"zero_offsets.q{j + 1}": offsets[j] for j in range(7)}
    with_strain = {**values, **distortion_coefficients(distortion - np.eye(3))}
    assert np.abs(model.residuals(model.vector(with_strain))).max() < 1e-12
    assert np.abs(model.residuals(model.vector(values))).max() > 5e-4  # the strain's values matter


def test_the_sensor_frame_carries_the_distortion(iiwa, rng):
    """compensation's sensor frame is (1 + s)(I + D) T p, by hand, and its inverse undoes it."""
    robot = synthetic_robot(iiwa, rng)
    setup = {**robot.setup, **TRUE_STRAIN}
    points = rng.uniform(-1, 1, (10, 3))
    transform, _ = robot.robot_to_sensor(setup)
    strain = np.array([[1.5e-3, 0.4e-3, 0.0], [0.4e-3, -1.0e-3, 0.0], [0.0, 0.0, 0.0]]) - TRUE_SCALE * np.eye(3)
    linear = (1.0 + setup["sensor_scale.s"]) * (np.eye(3) + strain)
    expected = spatial.transform_points(transform, points) @ linear.T
    np.testing.assert_allclose(robot.in_frame(points, "sensor", setup), expected, atol=1e-14)
    moved = dataclasses.replace(robot, setup=setup)
    np.testing.assert_allclose(moved.in_frame(moved.from_sensor(points), "sensor"), points, atol=1e-12)


def test_every_block_has_a_side_and_the_report_names_it():
    for block in BASE + EXTENSIONS:
        assert sides.side_of(block) in (sides.ROBOT, sides.SENSOR), block
    assert {b for b in EXTENSIONS if sides.side_of(b) == sides.SENSOR} == {
        "marker_offset",
        "sensor_scale",
        "sensor_distortion",
    }
    assert sides.side_of("residual_gp") == sides.UNATTRIBUTED
    report = loop_report(effects=["joint_compliance", "sensor_distortion"])
    assert report.to_json()["effects_sides"] == {"joint_compliance": "robot", "sensor_distortion": "sensor"}
    assert sides.with_sides(report.effects_added) == "joint_compliance (robot), sensor_distortion (sensor)"
    assert sides.with_sides(()) == "none"


def test_an_anisotropic_motion_capture_distortion_is_attributed_to_the_sensor():
    """A motion-capture frame read through I + M (anisotropic scales and a shear, the truth in the
    simulator's form), no robot effect but zero-offsets: the loop adds the distortion (and the
    isotropic scale M's trace leaves to sensor_scale), not joint compliance; its strain is M's
    symmetric traceless part within three of its stds, and validation falls to near the noise."""
    sets = {"optimization": {"poses": 16, "configurations": 80}, "validation": {"poses": 8, "configurations": 40}}
    spec = iiwa_scenario(
        "distorted",
        seed=33,
        plan={"reference_sensor": "motion_capture", "sets": sets},
        sensors={"motion_capture": {**MOCAP, "frame_distortion": DISTORTION}},
    )
    chain, sensor = simulated_sensor(spec, "motion_capture", REPO)
    from .test_loop_closure import closed

    report = closed(chain, sensor, loop_settings(mcmc=None)).report
    assert report.effects_added[0] == "sensor_distortion"
    assert "joint_compliance" not in report.effects_added
    assert set(report.effects_sides.values()) == {sides.SENSOR}  # nothing put down to the robot
    table = report.parameters.set_index("parameter")
    # without sensor_scale in the model (its cross-validated fall, 2.3 standard errors over 16 poses,
    # misses the t(K-1) threshold) the isotropic part TRUE_SCALE is unmodelled, and an omitted effect
    # can bias each strain by up to its own size: the tolerance says so, no more
    omitted = 0.0 if "sensor_scale" in report.effects_added else abs(TRUE_SCALE)
    for name, truth in TRUE_STRAIN.items():
        assert abs(table.at[name, "mean"] - truth) < 3 * table.at[name, "std"] + omitted, name
    if "sensor_scale" in report.effects_added:
        assert abs(table.at["sensor_scale.s", "mean"] - TRUE_SCALE) < 3 * table.at["sensor_scale.s", "std"]
    assert report.before["validation"]["rms_per_axis_mm"] * 1e-3 > 5 * MOCAP_NOISE
    # with sensor_scale in the model validation is at the noise (1.1x measured); without it (see above)
    # the omitted 167 ppm scale leaves 1.7x: measured, and the reason the bound is looser then
    closes = 1.25 if "sensor_scale" in report.effects_added else 2.0
    assert report.after["validation"]["rms_per_axis_mm"] * 1e-3 < closes * MOCAP_NOISE
