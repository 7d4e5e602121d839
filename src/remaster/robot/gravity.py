"""Joint torques exerted by gravity, computed by Pinocchio from the chain's mass properties.

They drive joint compliance: a joint of compliance c (rad/(N m)) deflects by c * tau, where tau
is the torque gravity exerts on it (the negative of the torque the motor must supply to hold).

Which payload the torques assume (`loaded_torques`). A URDF may already carry the tool: links
rigidly attached below the arm's last link (the child link of the last movable joint), such as a
tool plate or the flange mounted on it by fixed joints, with their mass. `chain_from_urdf` folds
them into the last body, so Pinocchio's torques already include them. The rule:

- the URDF carries a tool when any link rigidly attached below the last joint's own link has a
  mass > 0. Then the tool is those links, with the URDF's masses: the torques are the URDF's
  alone, the payload's part of them is the part of those links, and the configured payload
  (`loop_closure/payload`) is NOT added: adding it would count the tool twice, and the fitted
  payload compliance, which absorbs a payload other than the assumed one (c'_j = c_j (m / m0 - 1)),
  would come out as minus the joint's own (m = 0 on top of the URDF: the assumed m0 all extra);
- otherwise (the bundled iiwa URDF ends with a massless flange; a DH table has no masses) the
  configured payload is added at the flange, as before.

An arm without mass data (a DH table, a URDF without inertials) feels the payload alone, and a
compliance times that torque cannot follow the sag of its own links. Its weight is then a gravity
regressor instead (`gravity_regressor`): the torques on each joint of 1 kg at each moving joint frame's
origin and of its first moments along that frame's axes. Gravity's torque is linear in each body's
mass and first moment (its mass times its centre of mass), so the arm's own torque on joint j is a
combination of those columns whatever its masses are; the compliance fits one coefficient per joint,
body beyond it and column (c_j times the mass or moment the data put there), and no guess at the
masses is needed.

`Payload` says which payload the torques assume, and whether the arm's own weight is that regressor.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from . import kinematics
from .kinematics import KinematicChain, LinkInertia, pinocchio_model

STANDARD_GRAVITY = 9.80665  # m/s^2
UNIT_MASS = 1.0  # kg at each frame origin of the gravity regressor of an arm without mass data (module docstring)


def gravity_torques(
    chain: KinematicChain,
    q,
    payload_mass: float = 0.0,
    payload_com=(0.0, 0.0, 0.0),
    gravity=(0.0, 0.0, -STANDARD_GRAVITY),
) -> np.ndarray:
    """Torques (n, N) in N m that gravity exerts on each joint at configurations q (n, N).

    payload_mass (kg) at payload_com (m, in the flange frame) is added on top of the chain's own
    masses (a URDF's tool links included: `loaded_torques` decides whether to add one). The base
    frame's z axis points up unless `gravity` says otherwise. A chain without mass data (a DH
    table) feels the payload only.
    """
    import pinocchio as pin

    q = np.atleast_2d(np.asarray(q, dtype=float))
    model = pinocchio_model(chain)
    model.gravity.linear = np.asarray(gravity, dtype=float)
    if payload_mass > 0.0:
        com = chain.tool_transform[:3, :3] @ np.asarray(payload_com, dtype=float) + chain.tool_transform[:3, 3]
        model.appendBodyToJoint(chain.n_joints, pin.Inertia(payload_mass, com, np.zeros((3, 3))), pin.SE3.Identity())
    data = model.createData()
    return -np.array([pin.computeGeneralizedGravity(model, data, qi) for qi in q]).reshape(len(q), chain.n_joints)


@dataclass(frozen=True)
class Payload:
    """The payload the gravity torques assume. source: 'urdf' (the URDF's tool links, `links`,
    with their masses) or 'configuration' (the configured payload added at the flange); mass (kg);
    com (3,) m: in the flange frame for the configured payload, in the last joint's frame for the
    URDF's tool; configured_mass (kg): the configured payload, also when it was not added."""

    source: str
    mass: float
    com: tuple[float, float, float]
    links: tuple[str, ...] = ()
    configured_mass: float = 0.0
    mass_regressor: bool = False

    def report(self) -> dict:
        """JSON-ready, with a sentence saying which payload the torques assume and why."""
        if self.source == "urdf":
            why = (
                f"the URDF carries the tool (links {', '.join(self.links)}: {self.mass:.3g} kg below the last "
                f"joint's link): the gravity torques use the URDF's masses, and the configured payload "
                f"({self.configured_mass:.3g} kg) is not added on top of it"
            )
            frame = "last joint"
        else:
            why = (
                f"the URDF carries no tool below the last joint's link: the configured payload "
                f"({self.mass:.3g} kg) is added at the flange"
            )
            frame = "flange"
        if self.mass_regressor:
            why += (
                f"; the arm has no mass data: its weight is a gravity regressor, the torques of {UNIT_MASS:g} kg at "
                "each moving joint frame's origin and of its first moments, one compliance coefficient per "
                "joint, body beyond it and column"
            )
        return {
            "source": self.source,
            "arm_masses": "gravity regressor" if self.mass_regressor else "the robot description's",
            "mass_kg": self.mass,
            "com_m": list(self.com),
            "com_frame": frame,
            "links": list(self.links),
            "configured_mass_kg": self.configured_mass,
            "note": why,
        }


@dataclass(frozen=True, eq=False)
class LoadedTorques:
    """torques (n, N) N m: gravity's torque on each joint, payload included; payload_torques (n, N):
    the payload's part of it; payload: which payload they assume; body_torques (n, N, N, 4) N m: an
    arm without mass data's gravity regressor (`gravity_regressor`), None for an arm with masses."""

    torques: np.ndarray
    payload_torques: np.ndarray
    payload: Payload
    body_torques: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class UrdfTool:
    """The tool a URDF carries below the arm's last link: links (names with mass > 0), its mass
    properties in the last joint's frame, and the chain without it (the last body reduced to that
    joint's own link)."""

    links: tuple[str, ...]
    inertia: LinkInertia
    bare_chain: KinematicChain


def urdf_tool(chain: KinematicChain) -> UrdfTool | None:
    """The tool the chain's URDF carries (`module docstring`: the rule), or None when it carries
    none: no URDF, no mass data, or no link with mass rigidly attached below the last movable
    joint's own link."""
    if chain.urdf_xml is None or chain.inertias is None:
        return None
    root = ET.fromstring(chain.urdf_xml)  # already parsed once by chain_from_urdf: entities refused there
    links = {link.get("name"): link for link in root.findall("link")}
    joints = {joint.get("name"): joint for joint in root.findall("joint")}
    last = joints.get(chain.joint_names[-1])
    if last is None:
        return None
    own_link = last.find("child").get("link")
    fixed_children: dict[str, list[str]] = {}
    for joint in root.findall("joint"):
        if joint.get("type") == "fixed":
            fixed_children.setdefault(joint.find("parent").get("link"), []).append(joint.find("child").get("link"))
    below, stack = [], list(fixed_children.get(own_link, []))
    while stack:  # every link rigidly attached below the last joint's own link
        name = stack.pop()
        below.append(name)
        stack += fixed_children.get(name, [])
    massive = []
    for name in sorted(below):
        part = kinematics._link_inertia(links[name])  # the parser chain_from_urdf used: the same numbers
        if part is not None and part.mass > 0.0:
            massive.append(name)
    if not massive:
        return None
    own = kinematics._link_inertia(links[own_link])
    empty = LinkInertia(0.0, np.zeros(3), np.zeros((3, 3)))
    own = own if own is not None else empty
    body = chain.inertias[-1]
    bare = dataclasses.replace(chain, inertias=chain.inertias[:-1] + (own,))
    mass = body.mass - own.mass
    com = (body.mass * body.com - own.mass * own.com) / mass
    return UrdfTool(tuple(massive), LinkInertia(mass, com, np.zeros((3, 3))), bare)


def without_mass(chain: KinematicChain) -> bool:
    """Whether the chain has no mass data (a DH table, a URDF without inertials): every body massless."""
    return chain.inertias is None or not any(body.mass > 0.0 for body in chain.inertias)


def gravity_regressor(chain: KinematicChain, q, gravity=(0.0, 0.0, -STANDARD_GRAVITY), chunk: int = 50_000):
    """(n, N, N, 4) N m: [i, j, k] the torques gravity exerts on joint j at configuration q_i (n, N)
    of the mass properties of the body joint k moves, one at a time: [..., 0] UNIT_MASS at joint k's
    frame origin o_k, z_j . ((o_k - o_j) x m g); [..., 1:] a first moment of UNIT_MASS times 1 m along
    joint k's frame axes x, y, z (its centre of mass off the origin), z_j . (R_k e_a x m g). Zero for
    k < j: that body does not hang on joint j. Any body's weight loads joint j as a combination of
    them (Pinocchio's torque is linear in each body's mass and first moment). `chunk` rows at a time
    bound the joint frames' memory."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    weight = UNIT_MASS * np.asarray(gravity, dtype=float)
    out = np.zeros((len(q), chain.n_joints, chain.n_joints, 4))
    above = np.triu(np.ones((chain.n_joints, chain.n_joints)))[..., None]  # k >= j
    for start in range(0, len(q), chunk):
        frames = kinematics.ForwardKinematics(chain, q[start : start + chunk]).joint_frames()
        origins, rotations = frames[..., :3, 3], frames[..., :3, :3]  # (m, N, 3), (m, N, 3, 3)
        axes = np.einsum("mjab,jb->mja", rotations, chain.joint_axes)
        levers = origins[:, None, :, :] - origins[:, :, None, :]  # [m, j, k]: o_k - o_j
        mass = np.einsum("mja,mjka->mjk", axes, np.cross(levers, weight))
        columns = np.cross(np.swapaxes(rotations, -1, -2), weight)  # [m, k, a]: R_k e_a x m g
        moments = np.einsum("mjc,mkac->mjka", axes, columns)
        out[start : start + chunk] = np.concatenate([mass[..., None], moments], axis=-1) * above
    return out


def assumed_payload(chain: KinematicChain, payload_mass: float = 0.0, payload_com=(0.0, 0.0, 0.0)) -> Payload:
    """The payload `loaded_torques` assumes on this chain with this configured payload (kg, m
    flange frame): the URDF's tool when it carries one, else the configured payload."""
    return _assumed(chain, urdf_tool(chain), payload_mass, payload_com)


def _assumed(chain, tool: UrdfTool | None, payload_mass: float, payload_com) -> Payload:
    if tool is not None:
        com = tuple(float(c) for c in tool.inertia.com)
        return Payload("urdf", float(tool.inertia.mass), com, tool.links, float(payload_mass))
    com = tuple(float(c) for c in payload_com)
    return Payload("configuration", float(payload_mass), com, (), float(payload_mass), without_mass(chain))


def loaded_torques(chain: KinematicChain, q, payload_mass: float = 0.0, payload_com=(0.0, 0.0, 0.0)) -> LoadedTorques:
    """Gravity torques at q (n, N) with the payload the rule of the module docstring gives: the
    URDF's tool when it carries one (payload_mass is then not added), else payload_mass (kg) at
    payload_com (m, flange frame) added at the flange; the payload's part of them; and an arm
    without mass data's gravity regressor (`gravity_regressor`), whose torques are the payload's
    alone."""
    tool = urdf_tool(chain)
    payload = _assumed(chain, tool, payload_mass, payload_com)
    if tool is not None:
        torques = gravity_torques(chain, q)
        return LoadedTorques(torques, torques - gravity_torques(tool.bare_chain, q), payload)
    torques = gravity_torques(chain, q, payload_mass, payload_com)
    links = gravity_regressor(chain, q) if payload.mass_regressor else None
    return LoadedTorques(torques, torques - gravity_torques(chain, q), payload, links)


def tool_report(chain: KinematicChain) -> dict | None:
    """What a fit's report says of the URDF's tool: None when the URDF carries none (the loop
    closure's gravity torques then add the configured payload), else the tool's links, mass and
    centre of mass and that the configured payload is not added on top of it."""
    tool = urdf_tool(chain)
    if tool is None:
        return None
    return {
        "links": list(tool.links),
        "mass_kg": float(tool.inertia.mass),
        "com_m": tool.inertia.com.tolist(),
        "com_frame": "last joint",
        "note": "the URDF carries the tool: the loop closure's gravity torques use its masses and do not add "
        "the configured payload (loop_closure/payload) on top of it",
    }
