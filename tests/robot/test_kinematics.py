"""Batched forward kinematics against Pinocchio, chain loading from URDF and DH."""

import numpy as np
import pinocchio as pin
import pytest

from remaster import spatial
from remaster.errors import KinematicsError
from remaster.robot import kinematics

from ..conftest import IIWA_URDF, UR5_DH, UR5_URDF

TOLERANCE = 1e-9  # m


def pinocchio_marker_positions(urdf_path, flange, q, marker):
    """Reference: Pinocchio's own URDF parser and forward kinematics, one configuration at a time."""
    model = pin.buildModelFromUrdf(str(urdf_path))
    data = model.createData()
    frame = model.getFrameId(flange)
    out = []
    for qi in q:
        pin.framesForwardKinematics(model, data, qi)
        out.append(data.oMf[frame].act(np.asarray(marker, dtype=float)))
    return np.array(out)


def random_configurations(chain, rng, n):
    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    return rng.uniform(lower, upper, (n, chain.n_joints))


@pytest.mark.parametrize("marker", [[0.0, 0.0, 0.0], [0.1, 0.0, 0.02], [-0.1, 0.05, 0.3]])
def test_iiwa_markers_equal_pinocchio(iiwa, rng, marker):
    q = random_configurations(iiwa, rng, 200)
    expected = pinocchio_marker_positions(IIWA_URDF, "iiwa_link_ee", q, marker)
    np.testing.assert_allclose(kinematics.marker_positions(iiwa, q, marker), expected, rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("marker", [[0.0, 0.0, 0.031], [0.05, -0.02, 0.1]])
def test_dh_robot_markers_equal_pinocchio(ur5_dh, rng, marker):
    q = random_configurations(ur5_dh, rng, 200)
    expected = pinocchio_marker_positions(UR5_URDF, "flange", q, marker)
    np.testing.assert_allclose(kinematics.marker_positions(ur5_dh, q, marker), expected, rtol=0, atol=TOLERANCE)


def test_zero_offsets_add_to_joint_angles(iiwa, rng):
    q = random_configurations(iiwa, rng, 50)
    offsets = rng.normal(0.0, 0.01, 7)
    marker = [0.1, 0.0, 0.02]
    expected = pinocchio_marker_positions(IIWA_URDF, "iiwa_link_ee", q + offsets, marker)
    fk = kinematics.ForwardKinematics(iiwa, q)
    np.testing.assert_allclose(fk.points(marker, offsets), expected, rtol=0, atol=TOLERANCE)


def test_stack_of_offset_vectors_matches_one_at_a_time(iiwa, rng):
    q = random_configurations(iiwa, rng, 30)
    offsets = rng.normal(0.0, 0.01, (6, 7))
    fk = kinematics.ForwardKinematics(iiwa, q)
    stacked = fk.points([0.1, 0, 0.02], offsets)
    assert stacked.shape == (6, 30, 3)
    for walker, d in enumerate(offsets):
        np.testing.assert_allclose(stacked[walker], fk.points([0.1, 0, 0.02], d), rtol=0, atol=1e-12)
    poses = fk.flange_poses(offsets)
    assert poses.shape == (6, 30, 4, 4)
    np.testing.assert_allclose(poses[3], fk.flange_poses(offsets[3]), rtol=0, atol=1e-12)


def test_flange_poses_equal_pinocchio(iiwa, rng):
    q = random_configurations(iiwa, rng, 100)
    model = pin.buildModelFromUrdf(str(IIWA_URDF))
    data = model.createData()
    frame = model.getFrameId("iiwa_link_ee")
    poses = kinematics.flange_poses(iiwa, q)
    for qi, pose in zip(q, poses):
        pin.framesForwardKinematics(model, data, qi)
        np.testing.assert_allclose(pose, data.oMf[frame].homogeneous, rtol=0, atol=TOLERANCE)


def test_joint_frames_end_at_flange(iiwa, rng):
    q = random_configurations(iiwa, rng, 20)
    fk = kinematics.ForwardKinematics(iiwa, q)
    frames = fk.joint_frames()
    np.testing.assert_allclose(frames[:, -1] @ iiwa.tool_transform, fk.flange_poses(), atol=1e-12)


def test_iiwa_published_dimensions(iiwa):
    """Straight up at q = 0: flange at 0.36 + 0.42 + 0.40 + 0.126 m, joint axes alternate z / y."""
    pose = kinematics.flange_poses(iiwa, np.zeros((1, 7)))[0]
    np.testing.assert_allclose(pose[:3, 3], [0, 0, 1.306], atol=1e-12)
    frames = kinematics.ForwardKinematics(iiwa, np.zeros((1, 7))).joint_frames()[0]
    axes = np.abs(np.einsum("jab,jb->ja", frames[:, :3, :3], iiwa.joint_axes))
    np.testing.assert_allclose(axes[0::2], np.tile([0, 0, 1], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(axes[1::2], np.tile([0, 1, 0], (3, 1)), atol=1e-12)
    np.testing.assert_allclose(np.degrees(iiwa.upper), [170, 120, 170, 120, 170, 120, 175])
    np.testing.assert_allclose(iiwa.lower, -iiwa.upper)
    assert iiwa.inertias is not None and all(body.mass > 0 for body in iiwa.inertias)


def test_gravity_torques_of_chain_model_equal_urdf_model(iiwa, rng):
    """The chain keeps the URDF's mass properties, so Pinocchio built from it gives the same torques."""
    urdf_model = pin.buildModelFromUrdf(str(IIWA_URDF))
    chain_model = kinematics.pinocchio_model(iiwa)
    urdf_data, chain_data = urdf_model.createData(), chain_model.createData()
    for qi in random_configurations(iiwa, rng, 10):
        np.testing.assert_allclose(
            pin.computeGeneralizedGravity(chain_model, chain_data, qi),
            pin.computeGeneralizedGravity(urdf_model, urdf_data, qi),
            atol=1e-9,
        )


def test_pinocchio_model_of_dh_chain(ur5_dh, rng):
    model = kinematics.pinocchio_model(ur5_dh)
    data = model.createData()
    q = random_configurations(ur5_dh, rng, 20)
    poses = kinematics.flange_poses(ur5_dh, q)
    for qi, pose in zip(q, poses):
        pin.framesForwardKinematics(model, data, qi)
        np.testing.assert_allclose(data.oMf[model.getFrameId("flange")].homogeneous, pose, atol=TOLERANCE)


def test_modified_dh_matches_craig_formula(rng):
    rows = rng.uniform([-0.5, -np.pi, -0.5, -np.pi], [0.5, np.pi, 0.5, np.pi], (6, 4))
    flange = spatial.homogeneous(spatial.rot_y(0.3), [0.01, 0.02, 0.05])
    chain = kinematics.chain_from_dh(rows, "modified", flange=flange)
    q = rng.uniform(-np.pi, np.pi, (10, 6))
    for qi, pose in zip(q, kinematics.flange_poses(chain, q)):
        expected = np.eye(4)
        for (a, alpha, d, theta), angle in zip(rows, qi):
            expected = (
                expected
                @ spatial.homogeneous(spatial.rot_x(alpha), [a, 0, 0])
                @ spatial.homogeneous(spatial.rot_z(theta + angle), [0, 0, d])
            )
        np.testing.assert_allclose(pose, expected @ flange, atol=1e-12)


def test_standard_dh_matches_textbook_formula(rng):
    rows = rng.uniform([-0.5, -np.pi, -0.5, -np.pi], [0.5, np.pi, 0.5, np.pi], (5, 4))
    chain = kinematics.chain_from_dh(rows, "standard")
    q = rng.uniform(-np.pi, np.pi, (10, 5))
    for qi, pose in zip(q, kinematics.flange_poses(chain, q)):
        expected = np.eye(4)
        for (a, alpha, d, theta), angle in zip(rows, qi):
            expected = (
                expected
                @ spatial.homogeneous(spatial.rot_z(theta + angle), [0, 0, d])
                @ spatial.homogeneous(spatial.rot_x(alpha), [a, 0, 0])
            )
        np.testing.assert_allclose(pose, expected, atol=1e-12)


def test_urdf_and_dh_of_same_robot_agree(ur5_dh, rng):
    urdf = kinematics.chain_from_urdf(UR5_URDF.read_text(), "base_link", "flange")
    q = random_configurations(ur5_dh, rng, 50)
    assert kinematics.max_chain_difference(urdf, ur5_dh, q) < 1e-12
    rows = np.array(UR5_DH)
    rows[0, 2] += 1e-3
    shifted = kinematics.chain_from_dh(rows, "standard")
    assert kinematics.max_chain_difference(urdf, shifted, q) > 1e-4


def test_base_frame_other_than_root(iiwa, rng):
    """Starting at iiwa_link_1 drops joint 1: poses are relative to that link."""
    sub = kinematics.chain_from_urdf(IIWA_URDF.read_text(), "iiwa_link_1", "iiwa_link_ee")
    assert sub.n_joints == 6
    q = random_configurations(iiwa, rng, 10)
    full = kinematics.ForwardKinematics(iiwa, q)
    link1 = full.joint_frames()[:, 0]
    np.testing.assert_allclose(
        spatial.invert(link1) @ full.flange_poses(), kinematics.flange_poses(sub, q[:, 1:]), atol=1e-12
    )


@pytest.mark.parametrize(
    "base, flange, fragment",
    [
        ("iiwa_link_0", "tool0", "'tool0' is not a link"),
        ("world", "iiwa_link_ee", "'world' is not a link"),
        ("iiwa_link_ee", "iiwa_link_0", "is not below base"),
    ],
)
def test_missing_or_misplaced_frames_are_named(base, flange, fragment):
    with pytest.raises(KinematicsError, match=fragment) as info:
        kinematics.chain_from_urdf(IIWA_URDF.read_text(), base, flange, source="robot.urdf")
    assert "robot.urdf" in str(info.value)


def test_non_serial_and_unsupported_urdfs_are_rejected():
    two_parents = """<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="c"/></joint>
      <joint name="j2" type="revolute"><parent link="b"/><child link="c"/></joint></robot>"""
    with pytest.raises(KinematicsError, match="two parent joints"):
        kinematics.chain_from_urdf(two_parents, "a", "c")
    prismatic = """<robot name="r"><link name="a"/><link name="b"/>
      <joint name="slide" type="prismatic"><parent link="a"/><child link="b"/></joint></robot>"""
    with pytest.raises(KinematicsError, match="joint slide.*prismatic"):
        kinematics.chain_from_urdf(prismatic, "a", "b")
    with pytest.raises(KinematicsError, match="not valid XML"):
        kinematics.chain_from_urdf("<robot", "a", "b")


def test_a_mimic_joint_on_the_chain_is_refused_and_one_off_it_ignored():
    """A joint whose angle follows another's (<mimic>) cannot carry a zero-offset of its own: on
    the chain it is refused, naming the URDF and the joint; a gripper finger off the chain is not."""
    links = "".join(f'<link name="{n}"/>' for n in "abc")
    joint = '<joint name="{0}" type="revolute"><parent link="{1}"/><child link="{2}"/><axis xyz="0 0 1"/>{3}</joint>'
    mimic = '<mimic joint="j1" multiplier="-1"/>'
    on_chain = f'<robot name="r">{links}{joint.format("j1", "a", "b", "")}{joint.format("j2", "b", "c", mimic)}</robot>'
    with pytest.raises(KinematicsError, match=r"robot.urdf: joint j2: mimics joint 'j1'") as info:
        kinematics.chain_from_urdf(on_chain, "a", "c", source="robot.urdf")
    assert "refused" in str(info.value)
    off_chain = (
        f'<robot name="r">{links}<link name="f"/>{joint.format("j1", "a", "b", "")}{joint.format("j2", "b", "c", "")}'
        f"{joint.format('finger', 'b', 'f', mimic)}</robot>"
    )
    chain = kinematics.chain_from_urdf(off_chain, "a", "c", source="robot.urdf")
    assert chain.joint_names == ("j1", "j2")


def test_bad_dh_tables_are_rejected():
    with pytest.raises(KinematicsError, match="dh/convention"):
        kinematics.chain_from_dh(UR5_DH, "craig")
    with pytest.raises(KinematicsError, match="dh/rows"):
        kinematics.chain_from_dh([[0.0, 0.0, 0.1]], "standard")
    with pytest.raises(KinematicsError, match="non-finite.*row 1"):
        kinematics.chain_from_dh([[0, 0, 0.1, 0], [np.nan, 0, 0, 0]], "standard")
    with pytest.raises(KinematicsError, match="dh/flange"):
        kinematics.chain_from_dh(UR5_DH, "standard", flange=np.ones((4, 4)))


def random_axis_chain(rng, n_joints=6):
    """A chain with joint axes in arbitrary directions (not z), to exercise the general case."""
    transforms = spatial.homogeneous(
        spatial.euler_zyx_to_matrix(*rng.uniform(-np.pi, np.pi, (3, n_joints))), rng.uniform(-0.3, 0.3, (n_joints, 3))
    )
    axes = rng.normal(size=(n_joints, 3))
    axes[1] = [0.0, 0.0, -1.0]  # an axis opposite to z
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    tool = spatial.homogeneous(spatial.rot_x(0.4), [0.01, 0.02, 0.1])
    return kinematics.KinematicChain(
        name="skew",
        joint_names=tuple(f"j{i}" for i in range(n_joints)),
        joint_transforms=transforms,
        joint_axes=axes,
        tool_transform=tool,
        lower=np.full(n_joints, -np.inf),
        upper=np.full(n_joints, np.inf),
    )


def test_compiled_points_equal_pinocchio_for_any_axes_and_a_stack_of_offsets(rng):
    chain = random_axis_chain(rng)
    q = rng.uniform(-np.pi, np.pi, (40, chain.n_joints))
    offsets = rng.normal(0, 0.05, (3, chain.n_joints))
    marker = [0.05, -0.02, 0.03]
    fk = kinematics.ForwardKinematics(chain, q)
    stacked = fk.points(marker, offsets)
    assert stacked.shape == (3, 40, 3)
    for k in range(3):  # a stack of zero-offset vectors is each vector on its own
        np.testing.assert_allclose(stacked[k], fk.points(marker, offsets[k]), rtol=0, atol=1e-15)
    model = kinematics.pinocchio_model(chain)
    data = model.createData()
    for qi, p in zip(q + offsets[1], fk.points(marker, offsets[1])):
        pin.framesForwardKinematics(model, data, qi)
        np.testing.assert_allclose(p, data.oMf[model.getFrameId("flange")].act(np.array(marker)), atol=TOLERANCE)


@pytest.mark.parametrize("angle", [1e-9, 1e-4, 0.7, 2.5, np.pi - 1e-6])
def test_rotation_angle_is_the_angle_turned_even_near_zero(angle, rng):
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    assert spatial.rotation_angle(spatial.rot_axis(axis, angle)) == pytest.approx(angle, rel=1e-9)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 3e-5, 0.2, 2.0])
def test_a_rotation_vector_turns_by_its_length_about_its_direction(angle, rng):
    """Rodrigues against `rot_axis`, across the series/closed-form switch at 1e-4 rad."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    np.testing.assert_allclose(
        spatial.rotation_vector_to_matrix(angle * axis), spatial.rot_axis(axis, angle), atol=1e-15
    )


@pytest.mark.parametrize("robot", ["iiwa", "ur5_dh"])
def test_a_link_error_moves_the_frame_it_leads_to_in_its_own_axes(robot, request, rng):
    """F' = F D(xi): the translation lands in F's child frame (F's rotation carries it to the
    parent), the rotation turns the child frame about its own axes; a stack gives each set's own."""
    chain = request.getfixturevalue(robot)
    errors = rng.normal(0.0, 1e-3, (2, chain.n_joints + 1, 6))
    joints, tool = kinematics.perturbed_transforms(chain.joint_transforms, chain.tool_transform, errors)
    fixed = np.concatenate([chain.joint_transforms, chain.tool_transform[None]])
    moved = np.concatenate([joints, tool[:, None]], axis=1)
    for k in range(2):
        for transform, perturbed, xi in zip(fixed, moved[k], errors[k]):
            np.testing.assert_allclose(perturbed[:3, 3], transform[:3, 3] + transform[:3, :3] @ xi[:3], atol=1e-15)
            turn = transform[:3, :3].T @ perturbed[:3, :3]
            np.testing.assert_allclose(
                turn, spatial.rot_axis(xi[3:] / np.linalg.norm(xi[3:]), np.linalg.norm(xi[3:])), atol=1e-15
            )
    with pytest.raises(ValueError, match=rf"\(\.\.\., {chain.n_joints + 1}, 6\)"):
        kinematics.perturbed_transforms(chain.joint_transforms, chain.tool_transform, errors[0, :, :2])
