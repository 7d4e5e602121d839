"""The calibrated URDF is the calibrated model: Pinocchio's own parser reproduces remaster's
predictions; controller offsets in the controller's units."""

import numpy as np
import pandas as pd
import pinocchio as pin
import pytest
from scipy import stats

from remaster import spatial
from remaster.calibration import dh_table, exports, prediction
from remaster.campaigns import folders
from remaster.errors import InputError
from remaster.inference.parameter_blocks import link_errors, link_labels
from remaster.robot import kinematics
from remaster.units import DEG

from ..conftest import REPO, UR5_DH, UR5_URDF

MARKER = np.array([0.03, -0.02, 0.05])


def ur5_urdf_chain():
    return kinematics.chain_from_urdf(UR5_URDF.read_text(), source=str(UR5_URDF))


def pinocchio_points(xml, chain, q):
    """Marker positions (n, 3) in the base frame by Pinocchio from URDF text."""
    model = pin.buildModelFromXML(xml)
    data = model.createData()
    base, flange = model.getFrameId(chain.base_frame), model.getFrameId(chain.flange_frame)
    joints = [model.joints[model.getJointId(name)] for name in chain.joint_names]
    out = []
    for row in q:
        configuration = pin.neutral(model)
        for joint, angle in zip(joints, row):  # a continuous joint is (cos, sin) in Pinocchio
            values = [np.cos(angle), np.sin(angle)] if joint.nq == 2 else [angle]
            configuration[joint.idx_q : joint.idx_q + joint.nq] = values
        pin.framesForwardKinematics(model, data, configuration)
        placement = data.oMf[base].actInv(data.oMf[flange])
        out.append(placement.act(MARKER))
    return np.array(out)


def random_values(chain, rng):
    values = {f"zero_offsets.q{j + 1}": rng.normal(0.0, 0.5 * DEG) for j in range(chain.n_joints)}
    for _, column, name in link_labels(chain):
        values[name] = rng.normal(0.0, 1e-3 if column < 3 else 0.1 * DEG)
    return values


@pytest.mark.parametrize("robot", ["iiwa", "ur5"])
def test_pinocchio_reads_the_calibrated_urdf_as_the_calibrated_model(robot, iiwa, rng):
    chain = iiwa if robot == "iiwa" else ur5_urdf_chain()
    values = random_values(chain, rng)
    xml, left = exports.calibrated_urdf(chain, values)
    q = rng.uniform(np.maximum(chain.lower, -2.5), np.minimum(chain.upper, 2.5), (25, chain.n_joints))
    expected = prediction.robot_points(chain, q, MARKER, values, ("link_geometry",))
    np.testing.assert_allclose(pinocchio_points(xml, chain, q), expected, rtol=0, atol=1e-9)
    # and remaster's own parser agrees: the same link and joint names, a chain it reads again
    again = kinematics.chain_from_urdf(xml, chain.base_frame, chain.flange_frame)
    assert again.joint_names == chain.joint_names
    assert left == []


def test_a_chain_ending_on_a_joint_keeps_its_tool_twist_out_of_the_urdf_and_says_so(iiwa, rng):
    chain = kinematics.chain_from_urdf(iiwa.urdf_xml, "iiwa_link_0", "iiwa_link_7")
    values = random_values(chain, rng)
    xml, left = exports.calibrated_urdf(chain, values)
    assert len(left) == 1 and left[0].startswith("link_geometry.tool")
    q = rng.uniform(-1.0, 1.0, (10, chain.n_joints))
    held = {k: v for k, v in values.items() if ".tool." not in k}
    expected = prediction.robot_points(chain, q, MARKER, held, ("link_geometry",))
    np.testing.assert_allclose(pinocchio_points(xml, chain, q), expected, rtol=0, atol=1e-9)


def test_the_nominal_values_give_the_nominal_robot(iiwa, rng):
    xml, _ = exports.calibrated_urdf(iiwa, {})
    q = rng.uniform(-1.0, 1.0, (10, iiwa.n_joints))
    np.testing.assert_allclose(
        pinocchio_points(xml, iiwa, q), prediction.robot_points(iiwa, q, MARKER, {}), rtol=0, atol=1e-12
    )


# a campaign of too few poses for the jackknife (`jackknife.zero_offset_jackknife`)
NOT_COMPUTED = {"groups": 2, "method": "not computed: fewer than 3 poses", "parameters": {}}


def test_controller_offsets_in_degrees_and_radians_with_held_joints_flagged():
    table = pd.DataFrame(
        {
            "parameter": ["zero_offsets.q1", "zero_offsets.q2"],
            "mean": [0.0, 0.3 * DEG],
            "std": [np.nan, 0.01 * DEG],
            "q2.5": [np.nan, 0.28 * DEG],
            "q97.5": [np.nan, 0.32 * DEG],
            "status": ["held: not identifiable", "estimated"],
        }
    )
    offsets = exports.controller_offsets(["a1", "a2"], table, "paper", NOT_COMPUTED).set_index("joint")
    assert offsets.loc["a2", "correction_deg"] == pytest.approx(0.3)
    assert offsets.loc["a2", "correction_rad"] == pytest.approx(0.3 * DEG)
    assert offsets.loc["a2", "std_deg"] == pytest.approx(0.01)
    assert np.isnan(offsets.loc["a1", "std_deg"]) and offsets.loc["a1", "status"].startswith("held")


# one estimated zero-offset (0.3 deg, posterior std 0.03 deg) and its jackknife over 10 groups (std 0.05 deg)
ONE_JOINT = pd.DataFrame(
    {
        "parameter": ["zero_offsets.q1"],
        "mean": [0.3 * DEG],
        "std": [0.03 * DEG],
        "q2.5": [0.24 * DEG],
        "q97.5": [0.36 * DEG],
        "status": ["estimated"],
    }
)
JACKKNIFED = {"groups": 10, "parameters": {"zero_offsets.q1": {"u_between_deg": 0.04, "jackknife_std_deg": 0.05}}}


def test_controller_offsets_carry_the_between_design_component():
    """posterior std 0.03 deg, jackknife std 0.05 over 10 groups: u_between = 0.04, u_c = 0.05 set
    by the jackknife, dof = K - 1 = 9, k = t_0.975(9) = 2.262; no jackknife: k normal, U = 1.96 std."""
    table, between = ONE_JOINT, JACKKNIFED
    row = exports.controller_offsets(["a1"], table, "loop", between).iloc[0]
    assert row["u_between_deg"] == 0.04 and row["dof"] == pytest.approx(9.0)
    assert row["k"] == pytest.approx(2.262157, abs=1e-6) and row["U_deg"] == pytest.approx(2.262157 * 0.05, rel=1e-6)
    alone = exports.controller_offsets(["a1"], table, "loop", NOT_COMPUTED).iloc[0]
    assert np.isnan(alone["u_between_deg"]) and alone["U_deg"] == pytest.approx(1.959964 * 0.03, rel=1e-6)


def test_controller_offsets_carry_the_residual_fields_share_as_a_type_b_component():
    """posterior std 0.03 deg, jackknife std 0.05 over 10 groups (u_between 0.04) and a field's share
    u_model 0.06: u_c = sqrt(0.03^2 + 0.04^2 + 0.06^2) = 0.0781, dof = 9 u_c^4 / u_J^4 = 53.6 (only the
    jackknife's variance is estimated); without a jackknife U = 1.96 sqrt(0.03^2 + 0.06^2)."""
    table, between = ONE_JOINT, JACKKNIFED
    share = {"computed": True, "parameters": {"zero_offsets.q1": {"u_model_deg": 0.06}}}
    row = exports.controller_offsets(["a1"], table, "loop", between, share).iloc[0]
    u_c = np.sqrt(0.03**2 + 0.04**2 + 0.06**2)
    assert row["u_model_deg"] == 0.06 and row["dof"] == pytest.approx(53.5824, rel=1e-6)  # 9 u_c^4 / u_J^4
    assert row["U_deg"] == pytest.approx(stats.t.ppf(0.975, 9 * u_c**4 / 0.05**4) * u_c, rel=1e-9)
    alone = exports.controller_offsets(["a1"], table, "loop", NOT_COMPUTED, share).iloc[0]
    assert alone["U_deg"] == pytest.approx(stats.norm.ppf(0.975) * np.hypot(0.03, 0.06), rel=1e-9)
    none = exports.controller_offsets(["a1"], table, "loop", between, {"computed": False, "why": "closed"}).iloc[0]
    assert np.isnan(none["u_model_deg"]) and none["U_deg"] == pytest.approx(2.262157 * 0.05, rel=1e-6)


def test_a_correction_whose_posterior_is_its_priors_is_not_determined_and_names_what_is():
    """A loop-model zero-offset the data left at its prior (posterior std 0.9 of the prior's) is no
    estimate: no std, no U, and its status says so with the combination the data determine."""
    table = pd.DataFrame(
        {
            "parameter": ["zero_offsets.q1", "zero_offsets.q2"],
            "mean": [0.3 * DEG, 0.1 * DEG],
            "std": [0.01 * DEG, 0.45 * DEG],
            "q2.5": [0.28 * DEG, -0.8 * DEG],
            "q97.5": [0.32 * DEG, 1.0 * DEG],
            "status": ["estimated", "estimated"],
            "prior_dominated": [False, True],
            "posterior_to_prior_std": [0.02, 0.9],
            "determined_combination": ["", "+1*zero_offsets.q2 -1*link_geometry.L2.ry (std 0.01)"],
        }
    )
    offsets = exports.controller_offsets(["a1", "a2"], table, "loop", NOT_COMPUTED).set_index("joint")
    assert offsets.loc["a1", "status"] == "estimated" and offsets.loc["a1", "U_deg"] > 0
    status = offsets.loc["a2", "status"]
    assert status.startswith("not determined") and "0.90" in status and "link_geometry.L2.ry" in status
    assert np.isnan(offsets.loc["a2", "std_deg"]) and np.isnan(offsets.loc["a2", "U_deg"])
    assert offsets.loc["a2", "correction_deg"] == pytest.approx(0.1)


def test_a_dh_robot_gets_a_urdf_of_its_own_that_pinocchio_reads_as_calibrated(ur5_dh, rng):
    values = random_values(ur5_dh, rng)
    xml, left = exports.calibrated_urdf(ur5_dh, values)
    assert left == []
    q = rng.uniform(-2.5, 2.5, (20, ur5_dh.n_joints))
    expected = prediction.robot_points(ur5_dh, q, MARKER, values, ("link_geometry",))
    np.testing.assert_allclose(pinocchio_points(xml, ur5_dh, q), expected, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- calibrated DH table

FLANGE = spatial.homogeneous(spatial.rot_z(0.4) @ spatial.rot_x(0.2), np.array([0.01, -0.02, 0.03]))


def dh_points(table, q):
    """Marker positions (n, 3) of the DH table written by `calibrated_dh`, read back as a chain."""
    chain = kinematics.chain_from_dh(table["rows"], table["convention"], table["flange"])
    return prediction.robot_points(chain, q, MARKER, {})


def dh_form_values(chain, dh_chain, rows, convention, flange, rng):
    """Link geometry of `chain` (remaster's chain of the DH robot, URDF or DH) that makes it the
    robot of the DH table `rows` with every row perturbed (a, d by 1 mm, alpha by 0.1 deg; theta
    too but for a standard table's joint 1, which has no base transform to hold it): an error of
    DH form, written in the six-parameter link geometry as small_motion_of(F_j^-1 F'_j)."""
    noise = rng.normal(0.0, 1.0, (6, 4)) * [1e-3, 0.1 * DEG, 1e-3, 0.1 * DEG]
    if convention == "standard":
        noise[0, 3] = 0.0
    true = kinematics.chain_from_dh(np.array(rows, dtype=float) + noise, convention, flange)
    change = dh_table._frame_change(chain, dh_chain)  # remaster's body frames -> the DH table's
    joints = change[:-1] @ true.joint_transforms @ np.linalg.inv(change[1:])
    tool = change[-1] @ true.tool_transform
    motions = kinematics.small_motion_of(
        np.linalg.inv(np.concatenate([chain.joint_transforms, chain.tool_transform[None]]))
        @ np.concatenate([joints, tool[None]])
    )
    return {name: float(motions[row, column]) for row, column, name in link_labels(chain)}


@pytest.mark.parametrize("source", ["standard", "modified", "standard with a flange", "urdf with a dh table"])
def test_the_calibrated_dh_table_is_the_calibrated_model(source, rng):
    """Link-geometry errors of DH form (a perturbed DH table, in the six-parameter form) in DH rows
    of the campaign's convention: read back as a chain, the table gives remaster's calibrated
    predictions to 1e-9 m, and says it is exact."""
    convention = "modified" if source == "modified" else "standard"
    flange = FLANGE if source == "standard with a flange" else None
    dh = {"convention": convention, "rows": UR5_DH, **({"flange": flange.tolist()} if flange is not None else {})}
    chain = ur5_urdf_chain() if source.startswith("urdf") else kinematics.chain_from_dh(UR5_DH, convention, flange)
    dh_chain = kinematics.chain_from_dh(UR5_DH, convention, flange)
    values = dh_form_values(chain, dh_chain, UR5_DH, convention, flange, rng)
    q = rng.uniform(-2.5, 2.5, (30, 6))
    table = dh_table.calibrated_dh(chain, dh, values, q)
    assert table["exact"] and table["not_dh_form"] == []
    expected = prediction.robot_points(chain, q, MARKER, values, ("link_geometry",))
    np.testing.assert_allclose(dh_points(table, q), expected, rtol=0, atol=1e-9)
    assert table["max_position_difference_m"] < 1e-12 and table["max_orientation_difference_rad"] < 1e-12
    assert table["convention"] == convention and np.shape(table["rows"]) == (6, 4)


def test_zero_offsets_alone_land_in_theta_and_nothing_else_moves(ur5_dh, rng):
    offsets = rng.normal(0.0, 0.5 * DEG, 6)
    values = {f"zero_offsets.q{j + 1}": v for j, v in enumerate(offsets)}
    table = dh_table.calibrated_dh(ur5_dh, {"convention": "standard", "rows": UR5_DH}, values, np.zeros((1, 6)))
    rows = np.array(table["rows"])
    np.testing.assert_allclose(rows[:, 3], offsets, rtol=0, atol=1e-15)
    np.testing.assert_allclose(rows[:, :3], np.array(UR5_DH)[:, :3], rtol=0, atol=1e-15)
    np.testing.assert_allclose([c["theta_deg"] for c in table["change_from_nominal"]], offsets / DEG, atol=1e-12)
    assert table["flange"] == np.eye(4).tolist()


def test_a_twist_dh_cannot_hold_gets_the_nearest_row_and_says_how_far_it_is(rng):
    """A twist after a theta offset that is neither 0 nor pi (and joint 1's tilt in a standard table)
    is not of DH form: the table is flagged, names the transform, and its stated difference is the
    one its forward kinematics has from the calibrated model's."""
    rows = np.array(UR5_DH)
    rows[2, 3] = 0.3  # joint 3 with a theta offset
    chain = kinematics.chain_from_dh(rows, "standard")
    values = {"link_geometry.F3.rx": 0.2 * DEG, "link_geometry.F1.rx": 0.1 * DEG, "zero_offsets.q2": 0.01}
    q = rng.uniform(-2.5, 2.5, (40, 6))
    table = dh_table.calibrated_dh(chain, {"convention": "standard", "rows": rows.tolist()}, values, q)
    assert not table["exact"]
    assert [m.split(":")[0] for m in table["not_dh_form"]] == ["F1", "F3"]
    assert "base" in table["not_dh_form"][0] and "17.19 deg" in table["not_dh_form"][1]
    expected = kinematics.flange_poses(
        kinematics.perturbed_chain(chain, link_errors(chain, values)), q, zero_offsets=[0.0, 0.01, 0, 0, 0, 0]
    )
    written = kinematics.flange_poses(kinematics.chain_from_dh(table["rows"], "standard", table["flange"]), q)
    miss = np.max(np.linalg.norm(written[:, :3, 3] - expected[:, :3, 3], axis=1))
    assert table["max_position_difference_m"] == pytest.approx(miss, rel=1e-9)
    assert 1e-6 < miss < 0.3 * DEG * 1.2  # there, and of the size of the twists times the reach (< 1.2 m)


def test_a_campaign_without_a_dh_table_gets_none_and_a_clear_refusal():
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-twin")
    with pytest.raises(InputError, match="no DH table") as refusal:
        exports.calibrated_dh_tables(campaign, "laser_tracker", pd.DataFrame(), {})
    assert refusal.value.key == "robot/dh"


def test_a_model_dh_can_hold_whose_transforms_are_not_each_of_dh_form_gets_an_exact_table(rng):
    """Link errors of DH form, written into the six-parameter model and then moved between
    neighbouring transforms (a shift along a joint's own axis traded from one side of the joint to
    the other: the same robot): no transform is of DH form alone, the least-squares table holds the
    model exactly and says how it was found."""
    dh_chain = kinematics.chain_from_dh(UR5_DH, "standard")
    values = dh_form_values(dh_chain, dh_chain, UR5_DH, "standard", None, rng)
    # F3 Rot(z, q3) F4 = (F3 Tz(s)) Rot(z, q3) (Tz(-s) F4): 0.5 mm along joint 3's own axis moved
    # from one side of the joint to the other, the same robot, with F3 and F4 off the DH form
    shift = spatial.translation(z=0.5e-3)
    errors = link_errors(dh_chain, values)
    nominal = dh_chain.joint_transforms
    d3 = kinematics.small_motion(errors[2]) @ shift
    d4 = np.linalg.inv(nominal[3]) @ np.linalg.inv(shift) @ nominal[3] @ kinematics.small_motion(errors[3])
    moved = dict(values)
    for row, motion in ((2, kinematics.small_motion_of(d3)), (3, kinematics.small_motion_of(d4))):
        for column, part in enumerate(kinematics.LINK_MOTION):
            moved[f"link_geometry.F{row + 1}.{part}"] = float(motion[column])
    q = rng.uniform(-2.5, 2.5, (40, 6))
    np.testing.assert_allclose(
        prediction.robot_points(dh_chain, q, MARKER, moved, ("link_geometry",)),
        prediction.robot_points(dh_chain, q, MARKER, values, ("link_geometry",)),
        atol=1e-12,
    )
    table = dh_table.calibrated_dh(dh_chain, {"convention": "standard", "rows": UR5_DH}, moved, q)
    assert table["exact"] and table["not_dh_form"] == [] and "least squares" in table["method"]
    assert table["max_position_difference_m"] < 1e-9


def test_a_correction_the_priors_it_trades_against_set_is_not_determined():
    """A zero-offset whose own prior is wide (posterior std 0.02 of it) but which the data cannot
    tell from a link parameter of tight prior: the priors set 99 % of its variance, and its status
    says so, not "estimated"."""
    table = pd.DataFrame(
        {
            "parameter": ["zero_offsets.q1"],
            "mean": [0.1 * DEG],
            "std": [0.02 * DEG],
            "q2.5": [0.06 * DEG],
            "q97.5": [0.14 * DEG],
            "status": ["estimated"],
            "prior_dominated": [True],
            "posterior_to_prior_std": [0.02],
            "prior_share": [0.99],
            "determined_combination": ["+1*zero_offsets.q1 -1*link_geometry.F3.x (std 0.001)"],
        }
    )
    status = exports.controller_offsets(["a1"], table, "loop", NOT_COMPUTED).iloc[0]["status"]
    assert status.startswith("not determined: the priors set 99% of its posterior variance (its std 0.02 of")
    assert "link_geometry.F3.x" in status
    flat = table.assign(posterior_to_prior_std=[np.nan])  # a zero-offset has no prior of its own
    status = exports.controller_offsets(["a1"], flat, "loop", NOT_COMPUTED).iloc[0]["status"]
    assert status.startswith("not determined: the priors set 99% of its posterior variance (it has no prior")
