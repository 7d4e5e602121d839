"""Serial kinematic chains from a URDF or a DH table, and batched forward kinematics.

A chain of N revolute joints is stored in one form whatever its source:

    T_base_flange(q) = F_1 Rot(a_1, q_1) F_2 Rot(a_2, q_2) ... F_N Rot(a_N, q_N) F_tool

where F_j (4x4) is the fixed transform from the previous joint's frame (the base for j = 1)
to joint j's frame, a_j the unit joint axis in joint j's frame and F_tool the fixed transform
from the last joint's frame to the flange. Joint zero-offsets add to the joint angles:
q_j -> q_j + dtheta_j. Lengths in m, angles in rad.

Pinocchio is the reference (`pinocchio_model`); the batched NumPy code is the hot path.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field, replace

import numpy as np

from .. import _kernels, spatial
from ..errors import KinematicsError, quoted, refuse_millimetres

DH_CONVENTIONS = ("standard", "modified")
# A link's length (m) in a URDF origin or a DH table: the largest industrial arms reach about 4 m in
# all, so a single length of 5 m or more between base and flange is one written in mm. Checked where
# a robot description is read (a URDF here, a DH table by the campaign reader), not in chain_from_dh,
# which a fit also calls on its trial tables.
MAX_LINK_LENGTH = 5.0


@dataclass(frozen=True, eq=False)
class LinkInertia:
    """Mass properties of the rigid body moved by one joint (child link plus fixed descendants),
    expressed in that joint's frame: mass (kg), centre of mass (m, (3,)), inertia about the
    centre of mass (kg m^2, (3, 3))."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True, eq=False)
class KinematicChain:
    """A serial chain of revolute joints from a base frame to a flange frame.

    joint_transforms: (N, 4, 4) fixed transforms F_j; joint_axes: (N, 3) unit axes;
    tool_transform: (4, 4) F_tool; lower, upper: (N,) joint limits (rad, +-inf when unknown);
    inertias: one `LinkInertia` per joint when the model has mass data (URDF), else None;
    urdf_xml: the URDF text the chain came from, if any, for Pinocchio.
    """

    name: str
    joint_names: tuple[str, ...]
    joint_transforms: np.ndarray
    joint_axes: np.ndarray
    tool_transform: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    base_frame: str = "base"
    flange_frame: str = "flange"
    inertias: tuple[LinkInertia, ...] | None = None
    urdf_xml: str | None = field(default=None, repr=False)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def within_limits(self, q, tolerance: float = 1e-12) -> np.ndarray:
        """Boolean (...,) array: every joint of each configuration (..., N) lies within its limits."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.lower - tolerance) & (q <= self.upper + tolerance), axis=-1)


# --------------------------------------------------------------------------- URDF


def _floats(text: str | None, count: int, default: float, where: str) -> np.ndarray:
    if text is None:
        return np.full(count, default)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        raise KinematicsError(f"cannot read numbers from {quoted(text)}", key=where) from None
    if values.shape != (count,):
        raise KinematicsError(f"expected {count} numbers, got {quoted(text)}", key=where)
    if not np.isfinite(values).all():
        # float() reads 'nan' and 'inf': a pose or an axis built from them reaches the fit as
        # non-finite marker positions that name neither this file nor the joint
        raise KinematicsError(f"non-finite number(s) in {quoted(text)}: needs {count} finite numbers", key=where)
    return values


def _number(text: str | None, default: float, where: str, hint: str = "") -> float:
    """One number of a URDF attribute (default when absent); KinematicsError naming `where` if
    unreadable or not finite (float() reads 'nan' and 'inf'), `hint` added to the message."""
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        raise KinematicsError(f"cannot read a number from {quoted(text)}", key=where) from None
    if not np.isfinite(value):
        raise KinematicsError(f"non-finite number {quoted(text)}: needs a finite number{hint}", key=where)
    return value


def origin_transform(element: ET.Element, where: str) -> np.ndarray:
    """(4, 4) transform of a URDF element's <origin> (identity without one); `where` names it in errors."""
    origin = element.find("origin")
    if origin is None:
        return np.eye(4)
    xyz = _floats(origin.get("xyz"), 3, 0.0, f"{where}/origin/xyz")
    rpy = _floats(origin.get("rpy"), 3, 0.0, f"{where}/origin/rpy")
    return spatial.homogeneous(spatial.rpy_to_matrix(*rpy), xyz)


def _link_inertia(link: ET.Element) -> LinkInertia | None:
    inertial = link.find("inertial")
    if inertial is None:
        return None
    where = f"link {link.get('name')}/inertial"
    mass_el = inertial.find("mass")
    mass = _number(mass_el.get("value"), 0.0, f"{where}/mass") if mass_el is not None else 0.0
    pose = origin_transform(inertial, where)
    inertia_el = inertial.find("inertia")
    inertia = np.zeros((3, 3))
    if inertia_el is not None:
        get = lambda k: _number(inertia_el.get(k), 0.0, f"{where}/inertia/{k}")  # noqa: E731
        inertia = np.array(
            [
                [get("ixx"), get("ixy"), get("ixz")],
                [get("ixy"), get("iyy"), get("iyz")],
                [get("ixz"), get("iyz"), get("izz")],
            ]
        )
    rotation = pose[:3, :3]
    return LinkInertia(mass, pose[:3, 3], rotation @ inertia @ rotation.T)


def _combine(a: LinkInertia | None, b: LinkInertia | None) -> LinkInertia | None:
    """Mass properties of two rigid bodies fixed together (same frame)."""
    if a is None or b is None:
        return a if b is None else b
    mass = a.mass + b.mass
    if mass <= 0.0:
        return LinkInertia(0.0, np.zeros(3), np.zeros((3, 3)))
    com = (a.mass * a.com + b.mass * b.com) / mass

    def shifted(part: LinkInertia) -> np.ndarray:
        d = part.com - com
        return part.inertia + part.mass * (d @ d * np.eye(3) - np.outer(d, d))

    return LinkInertia(mass, com, shifted(a) + shifted(b))


def _moved(part: LinkInertia | None, transform: np.ndarray) -> LinkInertia | None:
    """Mass properties expressed in a parent frame, given parent <- child transform."""
    if part is None:
        return None
    rotation = transform[:3, :3]
    return LinkInertia(part.mass, spatial.transform_points(transform, part.com), rotation @ part.inertia @ rotation.T)


def chain_from_urdf(
    xml_text: str, base: str | None = None, flange: str | None = None, source: str = "URDF"
) -> KinematicChain:
    """Chain from URDF text between links `base` (default: the root) and `flange` (default: the
    single leaf). `source` names the file in error messages. Fixed joints fold into the fixed
    transforms; revolute and continuous joints are the chain's joints; any other joint type on
    the path is an error. A URDF declaring XML entities is refused.
    """
    try:
        return _chain_from_urdf(xml_text, base, flange, source)
    except KinematicsError as exc:
        if exc.file is not None:
            raise
        raise KinematicsError(exc.reason, file=source, key=exc.key, rows=exc.rows) from None


def _urdf_tree(xml_text: str, source: str) -> tuple[ET.Element, dict[str, ET.Element], dict[str, ET.Element]]:
    """(root, {link name: <link>}, {child link name: the <joint> that is its parent}) of a URDF,
    checked: no XML entities, valid XML under <robot>, every joint between defined links, a tree."""
    if "<!ENTITY" in xml_text:
        raise KinematicsError(
            "declares XML entities (<!ENTITY ...>): refused, a URDF needs none and their expansion can exhaust memory",
            file=source,
        )
    try:
        root = ET.fromstring(xml_text)
    except ET.ParseError as exc:
        raise KinematicsError(f"not valid XML: {exc}", file=source) from None
    if root.tag != "robot":
        raise KinematicsError("the root element is not <robot>", file=source)
    links = {link.get("name"): link for link in root.findall("link")}
    parent_of: dict[str, ET.Element] = {}
    for joint in root.findall("joint"):
        parent = joint.find("parent")
        child = joint.find("child")
        if parent is None or child is None:
            raise KinematicsError("joint without <parent> or <child>", file=source, key=f"joint {joint.get('name')}")
        child_name, parent_name = child.get("link"), parent.get("link")
        for link_name in (child_name, parent_name):
            if link_name not in links:
                raise KinematicsError(
                    f"refers to link {link_name!r}, which is not defined", file=source, key=f"joint {joint.get('name')}"
                )
        if child_name in parent_of:
            raise KinematicsError(
                f"link {child_name!r} has two parent joints ({parent_of[child_name].get('name')!r} and "
                f"{joint.get('name')!r}): not a tree, so not a serial chain",
                file=source,
            )
        parent_of[child_name] = joint
    return root, links, parent_of


def _chain_ends(links, parent_of, base: str | None, flange: str | None, source: str) -> tuple[str, str]:
    """(base, flange) link names: the given ones, checked to be links, or the tree's one root and
    its one leaf."""
    roots = [name for name in links if name not in parent_of]
    if len(roots) != 1:
        raise KinematicsError(f"expected one root link, found {sorted(roots)}", file=source)
    if base is None:
        base = roots[0]
    if flange is None:
        parents = {j.find("parent").get("link") for j in parent_of.values()}
        leaves = [name for name in links if name not in parents]
        if len(leaves) != 1:
            raise KinematicsError(
                f"the URDF has several leaf links {sorted(leaves)}: name the flange", file=source, key="flange"
            )
        flange = leaves[0]
    for key, frame in (("base", base), ("flange", flange)):
        if frame not in links:
            raise KinematicsError(
                f"frame {frame!r} is not a link of the URDF (links: {', '.join(sorted(links))})", file=source, key=key
            )
    return base, flange


def _joint_path(parent_of, base: str, flange: str, source: str) -> list[ET.Element]:
    """The joints from `base` to `flange`, in that order."""
    path: list[ET.Element] = []
    link = flange
    while link != base:
        if link not in parent_of:
            raise KinematicsError(
                f"flange {flange!r} is not below base {base!r} in the URDF tree", file=source, key="flange"
            )
        path.append(parent_of[link])
        link = parent_of[link].find("parent").get("link")
    path.reverse()
    return path


def _joint_axis(joint: ET.Element, where: str, source: str) -> np.ndarray:
    """A movable joint's unit axis (3,) (x when it gives none)."""
    axis = (
        _floats(joint.find("axis").get("xyz") if joint.find("axis") is not None else None, 3, 0.0, f"{where}/axis")
        if joint.find("axis") is not None
        else np.array([1.0, 0, 0])
    )
    norm = np.linalg.norm(axis)
    if norm < 1e-12:
        raise KinematicsError("joint axis has zero length", file=source, key=f"{where}/axis")
    return axis / norm


def _joint_limits(joint: ET.Element, kind: str, where: str, source: str) -> tuple[float, float]:
    """(lower, upper) rad of a revolute joint's <limit>, each infinite where not given; a continuous
    joint's are infinite."""
    limit = joint.find("limit")
    if kind != "revolute" or limit is None:
        return -np.inf, np.inf
    # an infinite limit passed without a word: the reader's check of joint readings against the
    # limits (degrees stored as radians) then never fires for that joint
    hint = ' (rad); a joint that turns without end is type="continuous", which has no limits'
    lo = _number(limit.get("lower"), -np.inf, f"{where}/limit/lower", hint)
    hi = _number(limit.get("upper"), np.inf, f"{where}/limit/upper", hint)
    if lo > hi:
        raise KinematicsError(
            f"lower limit {lo:g} is above upper limit {hi:g} (rad)", file=source, key=f"{where}/limit"
        )
    return lo, hi


def _refuse_mimic(joint: ET.Element, base: str, flange: str, source: str) -> None:
    """A movable joint of the chain that mimics another (<mimic>) is refused: its angle is another
    joint's times a ratio, so the zero-offset fit cannot give it an offset of its own."""
    mimic = joint.find("mimic")
    if mimic is not None:
        raise KinematicsError(
            f"mimics joint {mimic.get('joint')!r} (<mimic>): a joint of the chain from {base!r} to "
            f"{flange!r} must move on its own; refused (a mimic joint off the chain, e.g. a gripper's, is ignored)",
            file=source,
            key=f"joint {joint.get('name')}",
        )


def _chain_from_urdf(xml_text: str, base: str | None, flange: str | None, source: str) -> KinematicChain:
    root, links, parent_of = _urdf_tree(xml_text, source)
    base, flange = _chain_ends(links, parent_of, base, flange, source)
    path = _joint_path(parent_of, base, flange, source)
    children: dict[str, list[ET.Element]] = {}
    for joint in parent_of.values():
        children.setdefault(joint.find("parent").get("link"), []).append(joint)
    path_joints = {id(j) for j in path}

    def subtree_inertia(link_name: str) -> LinkInertia | None:
        """Link plus everything attached to it by fixed joints, off the chain's path."""
        total = _link_inertia(links[link_name])
        for joint in children.get(link_name, []):
            if id(joint) in path_joints or joint.get("type") != "fixed":
                continue
            child_inertia = subtree_inertia(joint.find("child").get("link"))
            total = _combine(total, _moved(child_inertia, origin_transform(joint, f"joint {joint.get('name')}")))
        return total

    names, transforms, axes, lower, upper, inertias = [], [], [], [], [], []
    pending = np.eye(4)  # fixed transform accumulated since the last movable joint
    body_inertia: LinkInertia | None = None
    for joint in path:
        name, kind = joint.get("name"), joint.get("type")
        where = f"joint {name}"
        origin = origin_transform(joint, where)
        refuse_millimetres(
            origin[:3, 3],
            MAX_LINK_LENGTH,
            "the bound of a plausible link length",
            file=source,
            key=f"{where}/origin/xyz",
            error=KinematicsError,
        )
        child = joint.find("child").get("link")
        if kind == "fixed":
            pending = pending @ origin
            if names:
                body_inertia = _combine(body_inertia, _moved(subtree_inertia(child), pending))
            continue
        if kind not in ("revolute", "continuous"):
            raise KinematicsError(
                f"joint type {kind!r} is not supported (revolute, continuous and fixed are)", file=source, key=where
            )
        _refuse_mimic(joint, base, flange, source)
        if names:
            inertias.append(body_inertia)
        axis = _joint_axis(joint, where, source)
        lo, hi = _joint_limits(joint, kind, where, source)
        names.append(name)
        transforms.append(pending @ origin)
        axes.append(axis)
        lower.append(lo)
        upper.append(hi)
        pending = np.eye(4)
        body_inertia = subtree_inertia(child)
    if not names:
        raise KinematicsError(f"no revolute joint between {base!r} and {flange!r}", file=source)
    inertias.append(body_inertia)
    has_mass = any(i is not None and i.mass > 0 for i in inertias)
    empty = LinkInertia(0.0, np.zeros(3), np.zeros((3, 3)))
    return KinematicChain(
        name=root.get("name", "robot"),
        joint_names=tuple(names),
        joint_transforms=np.array(transforms),
        joint_axes=np.array(axes),
        tool_transform=pending,
        lower=np.array(lower),
        upper=np.array(upper),
        base_frame=base,
        flange_frame=flange,
        inertias=tuple(i if i is not None else empty for i in inertias) if has_mass else None,
        urdf_xml=xml_text,
    )


# --------------------------------------------------------------------------- DH


def chain_from_dh(
    rows, convention: str = "standard", flange=None, name: str = "dh_robot", source: str = "DH table"
) -> KinematicChain:
    """Chain from DH rows [a (m), alpha (rad), d (m), theta offset (rad)], one per revolute joint.

    standard: T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i);
    modified (Craig): T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + q_i) Tz(d_i), row i holding
    (a_{i-1}, alpha_{i-1}, d_i, theta_i). `flange` is an optional 4x4 fixed transform after the
    last joint.
    """
    if convention not in DH_CONVENTIONS:
        raise KinematicsError(
            f"unknown DH convention {convention!r}; use one of {DH_CONVENTIONS}", file=source, key="dh/convention"
        )
    try:
        table = np.asarray(rows, dtype=float)
    except (TypeError, ValueError):
        raise KinematicsError("rows must be numbers [a, alpha, d, theta]", file=source, key="dh/rows") from None
    if table.ndim != 2 or table.shape[1] != 4 or table.shape[0] == 0:
        raise KinematicsError(
            f"rows must be a list of [a, alpha, d, theta], got shape {table.shape}", file=source, key="dh/rows"
        )
    bad = np.flatnonzero(~np.all(np.isfinite(table), axis=1))
    if bad.size:
        raise KinematicsError("non-finite DH values", file=source, key="dh/rows", rows=bad)
    tool = np.eye(4) if flange is None else np.asarray(flange, dtype=float)
    if (
        tool.shape != (4, 4)
        or not np.allclose(tool[3], [0, 0, 0, 1])
        or not np.allclose(tool[:3, :3] @ tool[:3, :3].T, np.eye(3), atol=1e-9)
    ):
        raise KinematicsError("flange must be a 4x4 rigid homogeneous transform", file=source, key="dh/flange")
    if np.linalg.det(tool[:3, :3]) < 0:  # orthonormal, but a mirror: no robot's flange is one
        raise KinematicsError(
            "flange must be a 4x4 rigid homogeneous transform: its rotation is orthonormal but its determinant "
            "is -1 (a reflection, not a rotation: a flipped axis?)",
            file=source,
            key="dh/flange",
        )

    def screw_z(theta, d):
        return spatial.homogeneous(spatial.rot_z(theta), np.array([0.0, 0.0, d]))

    def screw_x(a, alpha):
        return spatial.homogeneous(spatial.rot_x(alpha), np.array([a, 0.0, 0.0]))

    transforms = []
    after = np.eye(4)  # fixed part that follows the previous joint's rotation
    for a, alpha, d, theta in table:
        if convention == "standard":
            transforms.append(after @ spatial.homogeneous(spatial.rot_z(theta)))
            after = screw_z(0.0, d) @ screw_x(a, alpha)
        else:
            transforms.append(after @ screw_x(a, alpha) @ spatial.homogeneous(spatial.rot_z(theta)))
            after = screw_z(0.0, d)
    n = len(table)
    return KinematicChain(
        name=name,
        joint_names=tuple(f"joint{i + 1}" for i in range(n)),
        joint_transforms=np.array(transforms),
        joint_axes=np.tile([0.0, 0.0, 1.0], (n, 1)),
        tool_transform=after @ tool,
        lower=np.full(n, -np.inf),
        upper=np.full(n, np.inf),
    )


# --------------------------------------------------------------------------- forward kinematics


def _basis_with_z(axis) -> np.ndarray:
    """An orthonormal right-handed basis (3, 3) whose third column is the unit `axis` (the
    identity when the axis is z already, so that z-axis chains stay exact)."""
    axis = np.asarray(axis, dtype=float)
    if np.allclose(axis, [0.0, 0.0, 1.0], atol=0.0, rtol=0.0):
        return np.eye(3)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(axis, x), axis])


LINK_MOTION = ("x", "y", "z", "rx", "ry", "rz")  # the six small-motion parameters of a fixed transform


def small_motion(motion) -> np.ndarray:
    """D (..., 4, 4) of small-motion parameters (..., 6): a translation (x, y, z) m and a rotation
    vector (rx, ry, rz) rad, D = [exp([r]x), t]. The link-geometry error of a fixed transform F is
    F' = F D: a rigid motion of the frame F leads to, in that frame's own axes."""
    motion = np.asarray(motion, dtype=float)
    return spatial.homogeneous(spatial.rotation_vector_to_matrix(motion[..., 3:]), motion[..., :3])


def small_motion_of(transform) -> np.ndarray:
    """Small-motion parameters (..., 6) of rigid transforms (..., 4, 4) turning by less than pi:
    the inverse of `small_motion`, e.g. of F^-1 F' for a fixed transform F and its perturbed F'."""
    transform = np.asarray(transform, dtype=float)
    return np.concatenate([transform[..., :3, 3], spatial.matrix_to_rotation_vector(transform[..., :3, :3])], axis=-1)


def perturbed_transforms(joint_transforms, tool_transform, link_errors) -> tuple[np.ndarray, np.ndarray]:
    """(F'_1..F'_N (..., N, 4, 4), F'_tool (..., 4, 4)) with link-geometry errors (..., N + 1, 6),
    one set or a stack: F'_j = F_j D(xi_j) (`small_motion`), for F_1..F_N and F_tool in that order.
    Six parameters per fixed transform make the error model complete (any rigid error of any fixed
    transform is one); which of them the zero-offsets, registration and marker absorb is decided
    from the identification Jacobian (`inference.blocks`), not here."""
    errors = np.asarray(link_errors, dtype=float)
    transforms = np.concatenate([np.asarray(joint_transforms, dtype=float), np.asarray(tool_transform)[None]])
    if errors.shape[-2:] != (len(transforms), len(LINK_MOTION)):
        raise ValueError(
            f"link_errors must have shape (..., {len(transforms)}, {len(LINK_MOTION)}), got {errors.shape}"
        )
    out = transforms @ small_motion(errors)
    return out[..., :-1, :, :], out[..., -1, :, :]


def perturbed_chain(chain: KinematicChain, link_errors) -> KinematicChain:
    """The chain with link-geometry errors (N + 1, 6) (`perturbed_transforms`)."""
    joints, tool = perturbed_transforms(chain.joint_transforms, chain.tool_transform, link_errors)
    return replace(chain, joint_transforms=joints, tool_transform=tool)


@dataclass(frozen=True, eq=False)
class KernelForm:
    """The compiled kernels' form of a chain's fixed transforms: each joint axis turned onto z by
    a basis B_j, Rot(a_j, q) = B_j Rz(q) B_j^T, with B_j^T folded into the next fixed transform.
    rotations (N, 3, 3), shifts (N, 3); `start(point)` a flange-frame point in the last joint's
    z-aligned frame (3,). Built from the axes once (`of`), then cheaply for new fixed transforms
    (`with_transforms`), e.g. at each step of a link-geometry fit."""

    rotations: np.ndarray
    shifts: np.ndarray
    tool_transform: np.ndarray
    bases: np.ndarray

    @classmethod
    def of(cls, chain: KinematicChain) -> KernelForm:
        bases = np.array([_basis_with_z(a) for a in chain.joint_axes])
        return cls.with_bases(bases, chain.joint_transforms, chain.tool_transform)

    @classmethod
    def with_bases(cls, bases, joint_transforms, tool_transform) -> KernelForm:
        before = np.concatenate([np.eye(3)[None], np.swapaxes(bases[:-1], -1, -2)])
        rotations = np.ascontiguousarray(before @ joint_transforms[..., :3, :3] @ bases)
        shifts = np.ascontiguousarray((before @ joint_transforms[..., :3, 3, None])[..., 0])
        return cls(rotations, shifts, np.asarray(tool_transform, dtype=float), bases)

    def with_transforms(self, joint_transforms, tool_transform) -> KernelForm:
        """The same axes with other fixed transforms (N, 4, 4) and (4, 4), or stacks of them
        (m, N, 4, 4) and (m, 4, 4): rotations (m, N, 3, 3), shifts (m, N, 3)."""
        return self.with_bases(self.bases, joint_transforms, tool_transform)

    def start(self, point_in_flange) -> np.ndarray:
        """The flange point (3,) in the last joint's z-aligned frame: (3,), or (m, 3) for a stack of
        forms (`with_transforms` of stacked transforms) or of points (m, 3)."""
        point = spatial.transform_points(self.tool_transform, np.asarray(point_in_flange, dtype=float))
        return np.ascontiguousarray((self.bases[-1].T @ point[..., None])[..., 0])


class ForwardKinematics:
    """Batched forward kinematics of one chain at fixed joint readings q (n, N).

    The sines and cosines of the readings are computed once; zero-offsets enter through
    cos(q + d) = cos q cos d - sin q sin d, so each call costs a few vectorised operations.
    Zero-offsets may be one vector (N,) or a stack (m, N), e.g. one per ensemble walker.
    """

    def __init__(self, chain: KinematicChain, q):
        q = np.asarray(q, dtype=float)
        if q.ndim != 2 or q.shape[1] != chain.n_joints:
            raise ValueError(f"q must have shape (n, {chain.n_joints}), got {q.shape}")
        self.chain = chain
        self.q = q
        self.cos_q = np.cos(q)
        self.sin_q = np.sin(q)

    # the compiled kernels' form, built at the first point asked for: poses alone (a DH table's
    # least squares builds a chain per step) never need it
    @functools.cached_property
    def kernel(self) -> KernelForm:
        return KernelForm.of(self.chain)

    @functools.cached_property
    def kernel_cos_q(self) -> np.ndarray:
        return np.ascontiguousarray(self.cos_q.T)

    @functools.cached_property
    def kernel_sin_q(self) -> np.ndarray:
        return np.ascontiguousarray(self.sin_q.T)

    def flange_point(self, point_in_flange) -> np.ndarray:
        """A point given in the flange frame, in the last joint's z-aligned frame (3,)."""
        return self.kernel.start(point_in_flange)

    def _trig(self, zero_offsets):
        if zero_offsets is None:
            return self.cos_q, self.sin_q
        d = np.asarray(zero_offsets, dtype=float)
        if d.ndim == 2:
            d = d[:, None, :]
        cd, sd = np.cos(d), np.sin(d)
        return self.cos_q * cd - self.sin_q * sd, self.sin_q * cd + self.cos_q * sd

    def points(self, point_in_flange, zero_offsets=None) -> np.ndarray:
        """Positions in the base frame of a point fixed in the flange frame (3,), e.g. a marker.

        Returns (n, 3), or (m, n, 3) for a stack of m zero-offset vectors (m, N). Compiled.
        """
        offsets = np.zeros(self.chain.n_joints) if zero_offsets is None else np.asarray(zero_offsets, dtype=float)
        stack = np.atleast_2d(offsets)
        out = _kernels.points(
            self.kernel.rotations,
            self.kernel.shifts,
            self.flange_point(point_in_flange),
            self.kernel_cos_q,
            self.kernel_sin_q,
            np.cos(stack),
            np.sin(stack),
        )
        return out if offsets.ndim == 2 else out[0]

    def flange_poses(self, zero_offsets=None) -> np.ndarray:
        """Flange poses in the base frame, (n, 4, 4) or (m, n, 4, 4)."""
        cos, sin = self._trig(zero_offsets)
        k = spatial.skew(self.chain.joint_axes)
        k2 = k @ k
        pose = np.broadcast_to(np.eye(4), cos.shape[:-1] + (4, 4)).copy()
        for j in range(self.chain.n_joints):
            rotation = np.eye(3) + sin[..., j, None, None] * k[j] + (1.0 - cos[..., j, None, None]) * k2[j]
            pose = pose @ self.chain.joint_transforms[j]
            pose[..., :3, :3] = pose[..., :3, :3] @ rotation
        return pose @ self.chain.tool_transform

    def joint_frames(self, zero_offsets=None) -> np.ndarray:
        """Frame of every joint after its rotation, in the base frame: (n, N, 4, 4)."""
        if zero_offsets is not None and np.ndim(zero_offsets) == 2:
            raise ValueError("joint_frames takes one zero-offset vector")
        cos, sin = self._trig(zero_offsets)
        k = spatial.skew(self.chain.joint_axes)
        k2 = k @ k
        frames = np.empty(cos.shape[:-1] + (self.chain.n_joints, 4, 4))
        pose = np.broadcast_to(np.eye(4), cos.shape[:-1] + (4, 4))
        for j in range(self.chain.n_joints):
            pose = pose @ self.chain.joint_transforms[j]
            rotation = np.eye(3) + sin[..., j, None, None] * k[j] + (1.0 - cos[..., j, None, None]) * k2[j]
            pose = pose.copy()
            pose[..., :3, :3] = pose[..., :3, :3] @ rotation
            frames[..., j, :, :] = pose
        return frames


def flange_rotations(chain: KinematicChain, angles) -> np.ndarray:
    """Flange orientations (..., 3, 3) in the base frame at joint angles (..., N) rad: the
    rotation part of the chain alone (a full-pose probe's orientation needs no translation)."""
    angles = np.asarray(angles, dtype=float)
    k = spatial.skew(chain.joint_axes)
    k2 = k @ k
    cos, sin = np.cos(angles), np.sin(angles)
    rotation = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3))
    for j in range(chain.n_joints):
        turn = np.eye(3) + sin[..., j, None, None] * k[j] + (1.0 - cos[..., j, None, None]) * k2[j]
        rotation = rotation @ (chain.joint_transforms[j, :3, :3] @ turn)
    return rotation @ chain.tool_transform[:3, :3]


def marker_positions(chain: KinematicChain, q, marker, zero_offsets=None) -> np.ndarray:
    """Marker positions (n, 3) or (m, n, 3) in the base frame for joint readings q (n, N),
    a marker (3,) in the flange frame and optional zero-offsets (N,) or (m, N)."""
    return ForwardKinematics(chain, np.atleast_2d(q)).points(marker, zero_offsets)


def flange_poses(chain: KinematicChain, q, zero_offsets=None) -> np.ndarray:
    """Flange poses (n, 4, 4) or (m, n, 4, 4) in the base frame."""
    return ForwardKinematics(chain, np.atleast_2d(q)).flange_poses(zero_offsets)


def max_chain_difference(first: KinematicChain, second: KinematicChain, q) -> float:
    """Largest flange position difference (m) of two chains over configurations q (n, N),
    with orientation differences counted at a 1 m lever arm."""
    a = flange_poses(first, q)
    b = flange_poses(second, q)
    return float(max(np.abs(a[..., :3, 3] - b[..., :3, 3]).max(), np.abs(a[..., :3, :3] - b[..., :3, :3]).max()))


# --------------------------------------------------------------------------- Pinocchio reference


def pinocchio_model(chain: KinematicChain):
    """A Pinocchio model of the chain, with the flange as frame 'flange'.

    Built joint by joint from the chain's own numbers, with its mass properties when it has
    them, so it serves both as an FK reference and for gravity torques.
    """
    import pinocchio as pin

    model = pin.Model()
    model.name = chain.name
    parent = 0
    for j, name in enumerate(chain.joint_names):
        placement = pin.SE3(chain.joint_transforms[j][:3, :3].copy(), chain.joint_transforms[j][:3, 3].copy())
        joint = pin.JointModelRevoluteUnaligned(*chain.joint_axes[j])
        parent = model.addJoint(parent, joint, placement, name)
        if chain.inertias is not None:
            body = chain.inertias[j]
            model.appendBodyToJoint(
                parent, pin.Inertia(body.mass, body.com.copy(), body.inertia.copy()), pin.SE3.Identity()
            )
    tool = pin.SE3(chain.tool_transform[:3, :3].copy(), chain.tool_transform[:3, 3].copy())
    model.addFrame(pin.Frame("flange", parent, 0, tool, pin.FrameType.OP_FRAME))
    return model
