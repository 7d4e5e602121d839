"""The best URDF a URDF can be: the rigid chain nearest the loop-closed model where the data are.

loop.urdf holds the loop-closed model's zero-offsets and link geometry and assumes its other effects
(joint compliance, joint scale, harmonics, the residual GP) are applied beside it (loop_effects.yaml).
A tool that loads a URDF alone gets none of them, and the loop's zero-offsets were fitted with them
in place: loop.urdf alone can be as far from the loop model as paper.urdf. rigid.urdf is the chain a
URDF can hold (every joint origin in full, the zero-offsets) fitted by least squares to the
loop-closed model at configurations near the measured ones (`domain.MeasuredDomain`'s nearness):
at its marker, at the loop's marker offset for every model (the marker is the user's tool, not the
URDF's), and at its flange's whole pose, through points spread around the flange
(`flange_points`): fitted to the marker alone, the flange was free to tilt wherever a tilt absorbed
what the chain cannot hold, and a tool off the marker paid for it. The residual GP is not followed (its mean is not a
parametric effect), nor anything beyond the measured configurations. ik.urdf is the same fit with
only the zero-offsets, the base and the tool free: the links between the joints keep their nominal
geometry, so a closed-form inverse kinematics (IKFast, ur-analytic-ik: intersecting wrist axes)
stays exact on it, at the accuracy it states.

How far each URDF is from the loop model (median, 95th percentile and largest distance, mm) is
measured on a second, independent set of configurations near the measured ones, so the rigid fit is
scored on configurations it was not fitted to: at the marker and at the campaign's tools
(campaign.yaml's `tools`, else `DEFAULT_TOOLS`). SI inside (m, rad).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .. import identity, seeding
from ..calibration.exports import calibrated_urdf
from ..calibration.prediction import Calibration, Predictor
from ..campaigns.campaign import Campaign
from ..inference.blocks import BlockModel
from ..inference.evidence import forward_differences
from ..inference.least_squares import least_squares_mode
from ..inference.readings import Readings
from ..robot.kinematics import KinematicChain
from ..units import MM
from .workspace import fit_domain

RIGID_BLOCKS = ("marker_offset", "link_geometry")  # the marker offset held at the loop's value
URDF_PREFIXES = ("zero_offsets.", "link_geometry.")  # what a URDF's joint origins hold
# what keeps a closed-form IK solver exact: the zero-offsets, the base (the transform before joint 1)
# and the tool; the links between the joints keep their nominal geometry (intersecting wrist axes)
IK_PREFIXES = ("zero_offsets.", "link_geometry.F1.", "link_geometry.tool.")
CONFIGURATIONS = 1000  # near the measured ones, to fit and again (drawn apart) to score
# the flange's pose is fitted through its origin and a point this far along each of its axes (m):
# a tilt of 1 mrad moves them 0.1 mm, as much as it moves a tool 100 mm out
SPREAD = 0.1
# where a URDF's distance from the loop model is stated besides the marker when the campaign names
# no tools (campaign.yaml's `tools`): the flange and a tool 150 mm out along its axis (m, flange frame)
DEFAULT_TOOLS = {"flange": (0.0, 0.0, 0.0), "150 mm along the flange axis": (0.0, 0.0, 0.15)}


@dataclass(frozen=True)
class RigidFit:
    """values: {parameter: SI} of the zero-offsets and link geometry of the fitted chain (for
    `exports.calibrated_urdf`); ik_values: the same with only the zero-offsets, the base and the tool
    free (`IK_PREFIXES`: ik.urdf); distances: {file: {median_mm, p95_mm, max_mm}} of paper.urdf,
    loop.urdf, rigid.urdf and ik.urdf from the loop-closed model's marker over the scoring
    configurations; at_tools: {tool: {file: the same}} at the flange's points `tools` {tool: (3,) m,
    flange frame}, where the loop model's tool is its flange pose times the point (no marker
    offset); configurations: how many were fitted to and scored on (each)."""

    values: dict[str, float]
    ik_values: dict[str, float]
    distances: dict[str, dict[str, float]]
    configurations: int
    at_tools: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    tools: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    @property
    def report(self) -> dict:
        """JSON-ready, for workspace.json's `urdfs`."""
        return {
            "configurations": self.configurations,
            "where": "near the measured configurations (drawn apart from those the rigid fit used)",
            "distance_from_loop_model_mm": self.distances,
            "tools_m": {name: list(point) for name, point in self.tools.items()},
            "distance_at_tools_mm": self.at_tools,
            "not_followed": "the residual GP, and anything beyond the measured configurations",
        }


def _urdf_part(values: Mapping[str, float]) -> dict[str, float]:
    return {k: float(v) for k, v in values.items() if k.startswith(URDF_PREFIXES)}


def _marker_part(values: Mapping[str, float]) -> dict[str, float]:
    return {k: float(v) for k, v in values.items() if k.startswith("marker_offset.")}


def _tool_holdable(chain: KinematicChain) -> bool:
    """Whether the chain's URDF has a fixed joint after its last joint to hold the tool's link errors."""
    return not calibrated_urdf(chain, {"link_geometry.tool.x": MM})[1]


def flange_points() -> dict[str, np.ndarray]:
    """The points (3,) m in the flange frame a rigid chain is fitted to besides the marker: the flange's
    origin and `SPREAD` along each of its axes, so the fit holds the flange's whole pose and a tool
    anywhere on the flange is as right as the marker (module docstring)."""
    return {"flange": np.zeros(3)} | {
        f"flange {axis} {SPREAD / MM:.0f} mm": SPREAD * e for axis, e in zip("xyz", np.eye(3))
    }


def fit_rigid(chain: KinematicChain, loop: Calibration, fit_q, marker, free=URDF_PREFIXES) -> dict[str, float]:
    """The zero-offsets and link geometry {parameter: SI} whose chain puts the marker (3,) m, at the
    loop's marker offset, and the flange's pose (`flange_points`) nearest (least squares) the
    loop-closed model's at readings fit_q (n, N) rad, the parameters named by `free` (prefixes)
    fitted and the others of the URDF's at 0 (nominal), started from the loop's own values (the
    tool's link errors held at 0 where the URDF has no fixed joint to hold them)."""
    fit_q = np.asarray(fit_q, dtype=float)
    flange = loop.predictor(chain, fit_q, marker).flange_poses(loop.values)
    # the marker at the loop's marker offset (it is the user's marker); the flange's points carry none
    targets = [(marker, _marker_part(loop.values), loop.predictor(chain, fit_q, marker).points(loop.values))]
    targets += [(p, {}, tool_positions(flange, p)) for p in flange_points().values()]
    names = BlockModel(
        chain, Readings(np.arange(len(fit_q)), fit_q, targets[0][2]), marker, np.eye(4), RIGID_BLOCKS
    ).all_names
    held = {n: 0.0 for n in names if not n.startswith(free)}
    if not _tool_holdable(chain):  # a chain that ends on its last joint: no fixed joint holds the tool's errors
        held |= {n: 0.0 for n in names if n.startswith("link_geometry.tool.")}
    offsets = {n: 0.0 for n in names if n.startswith("marker_offset.")}
    models = [
        BlockModel(
            chain,
            Readings(np.arange(len(fit_q)), fit_q, target),
            point,
            np.eye(4),
            RIGID_BLOCKS,
            fixed=held | offsets | offset,
        )
        for point, offset, target in targets
    ]

    def residuals(theta):
        parts = [m.residuals(theta) for m in models]
        return np.concatenate([r.reshape(r.shape[:-2] + (-1,)) for r in parts], axis=-1)

    model = models[0]
    start = model.vector(loop.values)
    fitted = least_squares_mode(
        residuals, start, model.scale, lambda t: forward_differences(residuals, t), method="lm"
    ).x
    return _urdf_part(model.values(fitted))


def tool_positions(flange, point) -> np.ndarray:
    """Positions (n, 3) m of a point (3,) m of the flange frame on flange poses (n, 4, 4)."""
    return flange[:, :3, :3] @ np.asarray(point, dtype=float) + flange[:, :3, 3]


def distances_mm(points, target) -> dict[str, float]:
    """{median_mm, p95_mm, max_mm} of the distances between points (n, 3) and target (n, 3) m."""
    d = np.linalg.norm(np.asarray(points) - np.asarray(target), axis=-1) / MM
    return {"median_mm": float(np.median(d)), "p95_mm": float(np.quantile(d, 0.95)), "max_mm": float(d.max())}


def rigid_urdf_fit(campaign: Campaign, sensor: str, paper: Calibration, loop: Calibration, seed: int) -> RigidFit:
    """rigid.urdf's values and every URDF's distance from the loop-closed model (module docstring)
    for one sensor of a campaign: `CONFIGURATIONS` readings near the measured ones to fit, as many
    drawn apart to score, from the generators of (seed, 'rigid urdf', robot slug, 'fit'/'score')."""
    chain, data = campaign.chain, campaign.sensors[sensor]
    domain = fit_domain(chain, data)
    slug = identity.robot_slug(identity.robot_identity(campaign))

    def draw(purpose: str) -> np.ndarray:
        rng = seeding.generator(seed, "rigid urdf", slug, purpose)
        q = domain.nearness.draw(CONFIGURATIONS, rng, domain.limits_lower, domain.limits_upper)
        return np.where(domain.held, domain.lower, q)

    fit_q = draw("fit")
    values = fit_rigid(chain, loop, fit_q, data.marker)
    ik_values = fit_rigid(chain, loop, fit_q, data.marker, IK_PREFIXES)
    score_q = draw("score")
    target = loop.predictor(chain, score_q, data.marker).points(loop.values)
    marker = _marker_part(loop.values)
    at = Predictor(chain, score_q, data.marker, RIGID_BLOCKS)
    urdfs = {
        "paper.urdf": _urdf_part(paper.values),
        "loop.urdf": _urdf_part(loop.values),
        "rigid.urdf": values,
        "ik.urdf": ik_values,
    }
    distances = {name: distances_mm(at.points({**part, **marker}), target) for name, part in urdfs.items()}
    tools = {name: tuple(float(v) for v in point) for name, point in (campaign.tools or DEFAULT_TOOLS).items()}
    loop_flange = loop.predictor(chain, score_q, data.marker).flange_poses(loop.values)
    flanges = {name: at.flange_poses(part) for name, part in urdfs.items()}
    at_tools = {
        tool: {
            name: distances_mm(tool_positions(f, point), tool_positions(loop_flange, point))
            for name, f in flanges.items()
        }
        for tool, point in tools.items()
    }
    return RigidFit(values, ik_values, distances, CONFIGURATIONS, at_tools, tools)
