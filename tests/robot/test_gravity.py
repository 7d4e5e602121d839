"""Gravity torques: sign, payload and a hand-computed case."""

import numpy as np
import pytest

from remaster.inference.readings import ModelSettings, readings
from remaster.robot import kinematics
from remaster.robot.gravity import STANDARD_GRAVITY, gravity_torques, loaded_torques, tool_report


def test_point_mass_on_horizontal_arm():
    """One joint about y, a 2 kg payload 0.5 m out along x: gravity pulls it down, torque m g l about +y."""
    arm = kinematics.KinematicChain(
        name="arm",
        joint_names=("j",),
        joint_transforms=np.eye(4)[None],
        joint_axes=np.array([[0.0, 1.0, 0.0]]),
        tool_transform=np.array([[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]),
        lower=np.array([-np.inf]),
        upper=np.array([np.inf]),
    )
    tau = gravity_torques(arm, np.zeros((1, 1)), payload_mass=2.0)
    # r x F = (0.5, 0, 0) x (0, 0, -2 g) = (0, +g, 0)
    np.testing.assert_allclose(tau, [[2.0 * STANDARD_GRAVITY * 0.5]], rtol=1e-12)
    np.testing.assert_allclose(gravity_torques(arm, [[np.pi / 2]], payload_mass=2.0), 0.0, atol=1e-12)


def test_iiwa_payload_on_vertical_axis_adds_nothing_elsewhere_it_does(iiwa, rng):
    upright = np.zeros((1, 7))
    np.testing.assert_allclose(
        gravity_torques(iiwa, upright, payload_mass=1.0) - gravity_torques(iiwa, upright), 0.0, atol=1e-9
    )
    q = rng.uniform(iiwa.lower, iiwa.upper, (5, 7))
    bare = gravity_torques(iiwa, q)
    loaded = gravity_torques(iiwa, q, payload_mass=1.5, payload_com=[0.0, 0.0, 0.02])
    assert bare.shape == (5, 7)
    assert np.abs(loaded - bare).max() > 0.1


TOOL_PLATE = """
  <link name="tool_plate">
    <inertial>
      <origin xyz="0 0 0.02" rpy="0 0 0"/>
      <mass value="1.2"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.003"/>
    </inertial>
  </link>
  <joint name="tool_plate_mount" type="fixed">
    <parent link="iiwa_link_ee"/>
    <child link="tool_plate"/>
    <origin xyz="0 0 0" rpy="0 0 0"/>
  </joint>
</robot>"""


def with_tool_plate(flange: str):
    """The bundled iiwa URDF with a 1.2 kg tool plate (centre of mass 20 mm out along the flange
    axis) mounted on the flange, the chain ending at `flange` (the flange or the plate)."""
    from ..conftest import IIWA_URDF

    xml = IIWA_URDF.read_text().replace("</robot>", TOOL_PLATE)
    return kinematics.chain_from_urdf(xml, "iiwa_link_0", flange)


@pytest.mark.parametrize("flange", ["iiwa_link_ee", "tool_plate"])
def test_a_urdf_that_carries_the_tool_gives_the_payload(iiwa, rng, flange):
    """The URDF's tool plate is the payload: the torques are the bare arm's with 1.2 kg at the
    plate's centre of mass, its part of them is the payload's, and the configured 1 kg is not
    added on top; the report says so."""
    chain = with_tool_plate(flange)
    q = rng.uniform(iiwa.lower, iiwa.upper, (6, 7))
    loaded = loaded_torques(chain, q, payload_mass=1.0, payload_com=(0.0, 0.0, 0.02))
    expected = gravity_torques(iiwa, q, payload_mass=1.2, payload_com=[0.0, 0.0, 0.02])
    np.testing.assert_allclose(loaded.torques, expected, atol=1e-9)
    np.testing.assert_allclose(loaded.payload_torques, expected - gravity_torques(iiwa, q), atol=1e-9)
    payload = loaded.payload
    assert payload.source == "urdf" and payload.links == ("tool_plate",) and payload.configured_mass == 1.0
    assert payload.mass == pytest.approx(1.2) and payload.com == pytest.approx((0.0, 0.0, 0.045 + 0.02))
    note = payload.report()["note"]
    assert "tool_plate" in note and "configured payload (1 kg) is not added" in note
    assert ModelSettings(payload_mass=1.0).payload(chain) == payload
    assert tool_report(chain)["links"] == ["tool_plate"] and tool_report(iiwa) is None


def test_a_urdf_without_a_tool_takes_the_configured_payload(iiwa, rng):
    q = rng.uniform(iiwa.lower, iiwa.upper, (4, 7))
    loaded = loaded_torques(iiwa, q, payload_mass=1.5, payload_com=(0.0, 0.0, 0.02))
    np.testing.assert_array_equal(loaded.torques, gravity_torques(iiwa, q, 1.5, (0.0, 0.0, 0.02)))
    np.testing.assert_array_equal(loaded.payload_torques, loaded.torques - gravity_torques(iiwa, q))
    assert loaded.payload.source == "configuration" and loaded.payload.mass == 1.5
    assert "added at the flange" in loaded.payload.report()["note"]


def test_the_payload_compliance_of_a_urdf_tool_comes_out_zero_not_minus_the_joints(rng):
    """Joint deflections c tau, tau the true torques (arm and URDF tool plate), regressed per joint
    on the readings' regressors c tau_model + c' tau_payload (`readings.readings`): with the tool
    counted once c' = 0 and c is the truth; adding the configured 1 kg on top of the URDF's plate,
    as before, gave c' = -c."""
    import pandas as pd

    from remaster.campaigns.campaign import sensor_data

    chain = with_tool_plate("iiwa_link_ee")
    q = rng.uniform(np.maximum(chain.lower, -2.0), np.minimum(chain.upper, 2.0), (30, 7))
    table = pd.DataFrame({"set": "optimization", "pose": np.arange(30), "solution": np.zeros(30, np.int64)})
    for j in range(7):
        table[f"q{j + 1}"] = q[:, j]
    table[["x", "y", "z"]] = rng.normal(0.0, 0.5, (30, 3))  # positions play no part here
    sensor = sensor_data(
        "laser_tracker", {"kind": "laser_tracker", "marker": [0, 0, 0.05], "noise": 1e-5}, table, 7, "t.parquet"
    )
    data = readings(chain, sensor, "optimization", ModelSettings(payload_mass=1.0))
    true = gravity_torques(chain, q)  # the URDF's masses, tool plate included: the truth
    compliance = 50e-6
    old = gravity_torques(chain, q, 1.0, (0.0, 0.0, 0.02))  # the configured payload added on top
    for j in (1, 3):  # joints 2 and 4 (joint 6's own torque, link 7's, has the shape of the plate's)
        deflection = compliance * true[:, j]
        fitted = np.linalg.lstsq(
            np.column_stack([data.torques[:, j], data.payload_torques[:, j]]), deflection, rcond=None
        )[0]
        assert fitted == pytest.approx([compliance, 0.0], abs=1e-12)
        before = np.linalg.lstsq(np.column_stack([old[:, j], old[:, j] - true[:, j]]), deflection, rcond=None)[0]
        assert before == pytest.approx([compliance, -compliance], rel=1e-6)


def test_predictions_take_the_torques_the_fit_took(rng):
    """`remaster predict` and the fit's readings assume the same payload: on a URDF that carries its
    tool, the predictor's compliance torques are the readings' (the plate once, not plus 1 kg)."""
    from remaster.calibration import prediction

    chain = with_tool_plate("iiwa_link_ee")
    q = rng.uniform(chain.lower, chain.upper, (5, 7))
    settings = ModelSettings(payload_mass=1.0)
    predictor = prediction.Predictor(chain, q, np.zeros(3), ("joint_compliance",), settings)
    loaded = loaded_torques(chain, q, settings.payload_mass, settings.payload_com)
    np.testing.assert_array_equal(predictor.model.data.torques, loaded.torques)
    np.testing.assert_array_equal(predictor.model.data.payload_torques, loaded.payload_torques)


def test_the_gravity_regressor_is_pinocchios_torque_of_each_bodys_mass_and_first_moments(iiwa, rng):
    import dataclasses

    from remaster.robot import gravity
    from remaster.robot.kinematics import LinkInertia

    q = rng.uniform(np.maximum(iiwa.lower, -2.5), np.minimum(iiwa.upper, 2.5), (50, 7))
    regressor = gravity.gravity_regressor(iiwa, q, chunk=7)  # several chunks

    def one_body(k, com):
        bodies = tuple(LinkInertia(float(i == k), np.asarray(com, float), np.zeros((3, 3))) for i in range(7))
        return gravity_torques(dataclasses.replace(iiwa, inertias=bodies), q)

    for k in range(7):
        at_origin = one_body(k, np.zeros(3))
        np.testing.assert_allclose(regressor[:, :, k, 0], at_origin, rtol=0, atol=1e-10)
        for axis in range(3):  # 1 kg 1 m along the axis is the origin's mass plus a first moment of 1 kg m
            moment = one_body(k, np.eye(3)[axis]) - at_origin
            np.testing.assert_allclose(regressor[:, :, k, 1 + axis], moment, rtol=0, atol=1e-10)
    assert np.all(regressor[:, 1, 0] == 0.0)  # the body joint 1 moves does not hang on joint 2


def test_an_arm_without_mass_data_gets_a_regressor_that_spans_its_own_weight(iiwa, rng):
    """The iiwa without its inertials (as a DH table would give it): a compliance per joint, body and
    column of the regressor follows the real arm's own torque (the URDF's masses, which the regressor
    never sees) exactly on every joint gravity loads, where the payload alone leaves a fifth or more;
    the payload's part is the payload's, and the arm's torques are the payload's alone."""
    import dataclasses

    from remaster.robot import gravity

    bare = dataclasses.replace(iiwa, inertias=None)
    assert gravity.without_mass(bare) and not gravity.without_mass(iiwa)
    q = rng.uniform(np.maximum(iiwa.lower, -2.5), np.minimum(iiwa.upper, 2.5), (400, 7))
    loaded = loaded_torques(bare, q, payload_mass=2.5, payload_com=(0.0, 0.0, 0.03))
    assert loaded.payload.mass_regressor and loaded.payload.report()["arm_masses"] == "gravity regressor"
    payload = gravity_torques(bare, q, 2.5, (0.0, 0.0, 0.03))
    np.testing.assert_allclose(loaded.payload_torques, payload, rtol=0, atol=1e-9)
    np.testing.assert_allclose(loaded.torques, payload, rtol=0, atol=1e-9)
    own = gravity_torques(iiwa, q)  # the real arm's weight alone

    def unexplained(columns, joint):
        """The share of the real torque's spread a least-squares combination of columns cannot follow."""
        target = own[:, joint]
        fitted = columns @ np.linalg.lstsq(columns, target, rcond=None)[0]
        return np.linalg.norm(target - fitted) / np.linalg.norm(target - target.mean())

    for joint in (1, 2, 3, 4, 5):  # joints 2 to 6: the ones gravity loads (joint 1 is vertical)
        regressor = unexplained(loaded.body_torques[:, joint, joint:].reshape(len(q), -1), joint)
        assert regressor < 1e-9
    for joint in (1, 2, 3, 4):  # joint 6's own load already has the payload's shape here
        assert unexplained(loaded.payload_torques[:, joint, None], joint) > 0.2
    assert loaded_torques(iiwa, q, payload_mass=2.5).body_torques is None
