"""A calibration in the robot's own terms: a calibrated URDF, the effects a URDF cannot hold, and the
zero-offset corrections as a controller takes them.

**Calibrated URDF.** The input URDF with the same links and joints (it drops into an existing ROS /
MoveIt set-up), each joint origin on the chain rewritten so that the URDF's forward kinematics is
the calibrated model's. For joint j with fixed transform F_j (the fixed joints since the previous
joint times joint j's origin O_j), link-geometry errors giving F'_j (`kinematics.perturbed_transforms`)
and zero-offset d_j (true angle = reading + d_j):

    F'_j Rot(a_j, q + d_j) = P_j O'_j Rot(a_j, q)   with   O'_j = O_j F_j^-1 F'_j Rot(a_j, d_j),

so a robot commanded to q is where the calibrated model says. The tool's link errors go into the
last fixed joint before the flange (a chain that ends on a joint has none: then they stay in the
YAML). What a URDF cannot hold (joint compliance, joint scale, drift, the marker offset, the residual
GP, the sensor's set-up) is listed in `loop_effects.yaml` with values, stds and units. A campaign
given as a DH table gets the calibrated DH table too (`dh_table`), exact or saying how far it is.

**Controller offsets.** Per joint: the correction to add to the controller's zero (true angle =
reading + correction), in degrees (KUKA and most industrial controllers) and radians (UR), with its
posterior std and 95 % interval, for the paper's model and the loop-closed model; held joints get
none and say why. Each correction's expanded uncertainty holds how far it moves with the poses
measured too: u_between, the zero-offsets' spread across designs beyond the posterior's
(loop_closure.json between_design, `remaster.loop.jackknife`), and for the loop-closed model,
where its residual holds a field it lacks (the residual GP added, or the loop not closed), u_model,
that field's share (loop_closure.json model_error_share, `remaster.loop.model_error_share`);
u_c = sqrt(std^2 + u_between^2 + u_model^2), its effective degrees of freedom (Welch-Satterthwaite,
`uncertainty.with_between`) and U = k u_c with k = t_0.975(dof). Where the jackknife was not
computed (too few poses), u_between is NaN and U = k sqrt(std^2 + u_model^2) at k normal.

SI inside (m, rad).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import spatial
from ..calibration import dh_table, ur_kinematics
from ..calibration.prediction import SETUP_BLOCKS, Calibration, loop_calibration, paper_calibration
from ..campaigns.campaign import Campaign
from ..errors import InputError
from ..inference.model import by_parameter
from ..inference.parameter_blocks import calibrated_transforms
from ..inference.uncertainty import coverage_factor, with_between
from ..loop.refit import PRIOR_DOMINATED
from ..loop.result import LoopReport
from ..robot.kinematics import KinematicChain, origin_transform
from ..units import DEG

URDF_BLOCKS = ("zero_offsets", "link_geometry")  # what the joint origins hold
SIGN = "true joint angle = controller reading + correction: add the correction to the controller's zero"
OFFSET_COLUMNS = [
    "joint",
    "model",
    "correction_deg",
    "std_deg",
    "q2.5_deg",
    "q97.5_deg",
    "correction_rad",
    "std_rad",
    "u_between_deg",
    "u_model_deg",
    "U_deg",
    "dof",
    "k",
    "status",
]


def _path(root: ET.Element, base: str, flange: str) -> list[ET.Element]:
    """The joints from base to flange, in order."""
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
    path, link = [], flange
    while link != base:
        joint = by_child[link]
        path.append(joint)
        link = joint.find("parent").get("link")
    return path[::-1]


def _set_origin(joint: ET.Element, transform: np.ndarray) -> None:
    origin = joint.find("origin")
    if origin is None:
        origin = ET.SubElement(joint, "origin")
    yaw, pitch, roll = spatial.matrix_to_euler_zyx(transform[:3, :3])
    origin.set("xyz", " ".join(repr(float(v)) for v in transform[:3, 3]))
    origin.set("rpy", " ".join(repr(float(v)) for v in (roll, pitch, yaw)))


def nominal_urdf(chain: KinematicChain) -> str:
    """A URDF of a chain that came without one (a DH table): links <name>_link_1..N between its base
    and flange frames, its joints with their fixed transforms, axes and limits, and a fixed joint
    `<name>_flange_fixed` holding the tool transform."""
    root = ET.Element("robot", name=chain.name)
    links = [chain.base_frame] + [f"{chain.name}_link_{j + 1}" for j in range(chain.n_joints)] + [chain.flange_frame]
    for link in links:
        ET.SubElement(root, "link", name=link)
    for j, name in enumerate(chain.joint_names):
        bounded = np.isfinite(chain.lower[j]) and np.isfinite(chain.upper[j])
        joint = ET.SubElement(root, "joint", name=name, type="revolute" if bounded else "continuous")
        ET.SubElement(joint, "parent", link=links[j])
        ET.SubElement(joint, "child", link=links[j + 1])
        _set_origin(joint, chain.joint_transforms[j])
        ET.SubElement(joint, "axis", xyz=" ".join(repr(float(v)) for v in chain.joint_axes[j]))
        if bounded:
            ET.SubElement(
                joint,
                "limit",
                lower=repr(float(chain.lower[j])),
                upper=repr(float(chain.upper[j])),
                effort="0",
                velocity="0",
            )
    tool = ET.SubElement(root, "joint", name=f"{chain.name}_flange_fixed", type="fixed")
    ET.SubElement(tool, "parent", link=links[-2])
    ET.SubElement(tool, "child", link=links[-1])
    _set_origin(tool, chain.tool_transform)
    return ET.tostring(root, encoding="unicode")


def calibrated_urdf(chain: KinematicChain, values: Mapping[str, float]) -> tuple[str, list[str]]:
    """(URDF text, what it could not hold) of the chain with zero-offsets and link geometry from
    `values` {parameter: SI} folded into its joint origins (module docstring); a chain without a
    URDF gets `nominal_urdf`'s."""
    root = ET.fromstring(chain.urdf_xml if chain.urdf_xml is not None else nominal_urdf(chain))
    path = _path(root, chain.base_frame, chain.flange_frame)
    movable = [j for j in path if j.get("type") in ("revolute", "continuous")]
    joints, tool = calibrated_transforms(chain, values)
    for j, element in enumerate(movable):
        origin = origin_transform(element, f"joint {element.get('name')}")
        _set_origin(element, origin @ np.linalg.inv(chain.joint_transforms[j]) @ joints[j])
    left = []
    after = path[path.index(movable[-1]) + 1 :]
    if np.any(tool != chain.tool_transform):
        if after:
            last = after[-1]
            origin = origin_transform(last, f"joint {last.get('name')}")
            _set_origin(last, origin @ np.linalg.inv(chain.tool_transform) @ tool)
        else:
            left.append("link_geometry.tool: the chain ends on its last joint, no fixed joint to hold it")
    root.set("name", root.get("name", "robot"))
    comment = ET.Comment(" calibrated by remaster: zero-offsets and link geometry folded into the joint origins ")
    root.insert(0, comment)
    return ET.tostring(root, encoding="unicode"), left


def effects_yaml(calibration: Calibration, table: pd.DataFrame | None, left: list[str], extra: Mapping) -> dict:
    """The loop-closed model's effects a URDF cannot hold: per block, parameter: {value, std, unit}
    in display units (`table`: loop_closure.json's refit parameters), with the model settings and
    what the URDF could not hold."""
    out: dict = {"convention": SIGN, "urdf_holds": list(URDF_BLOCKS), "effects": {}}
    if table is not None and not table.empty:
        rows = table[~table["block"].isin(URDF_BLOCKS + SETUP_BLOCKS)]
        for block, part in rows.groupby("block", sort=False):
            out["effects"][str(block)] = {
                str(r["parameter"]): {
                    "value": float(r["mean_display"]),
                    "unit": str(r["unit"]),
                    "std": None if pd.isna(r["std_display"]) else float(r["std_display"]),
                    "status": not_determined(r),
                }
                for _, r in part.iterrows()
            }
    out["payload"] = {"mass_kg": calibration.settings.payload_mass, "com_m": list(calibration.settings.payload_com)}
    out["not_in_urdf"] = list(left)
    out.update(extra)
    return out


def controller_offsets(
    joint_names, table: pd.DataFrame, model: str, between: Mapping, share: Mapping | None = None
) -> pd.DataFrame:
    """`OFFSET_COLUMNS` per joint of one model from its parameter table (parameter, mean, std,
    q2.5, q97.5 SI, status), its between-design component (`jackknife.zero_offset_jackknife`:
    groups, parameters {name: u_between_deg, jackknife_std_deg}, empty when not computed) and the
    share of a residual field it lacks (`model_error_share.zero_offset_model_error`: parameters
    {name: u_model_deg}; None or not computed: none)."""
    table = by_parameter(table)
    spread = between["parameters"]
    field = (share or {}).get("parameters") or {}
    rows = []
    for j, joint in enumerate(joint_names):
        name = f"zero_offsets.q{j + 1}"
        r = table.loc[name]
        status = not_determined(r)
        estimated = status == "estimated"
        value = float(r["mean"])
        std = float(r["std"]) / DEG if estimated else np.nan
        u_m = float(field[name]["u_model_deg"]) if estimated and name in field else np.nan
        if estimated and name in spread:
            u_b, u_j = float(spread[name]["u_between_deg"]), float(spread[name]["jackknife_std_deg"])
            u_c, dof = (float(v) for v in with_between(std, u_b, u_j, int(between["groups"]), np.nan_to_num(u_m)))
        else:  # held, or no between-design component computed: the posterior and the field's share
            u_b, u_c, dof = np.nan, float(np.hypot(std, np.nan_to_num(u_m))), np.inf if estimated else np.nan
        k = coverage_factor(dof)
        rows.append(
            {
                "joint": joint,
                "model": model,
                "correction_deg": value / DEG,
                "std_deg": std,
                "q2.5_deg": float(r["q2.5"]) / DEG if estimated else np.nan,
                "q97.5_deg": float(r["q97.5"]) / DEG if estimated else np.nan,
                "correction_rad": value,
                "std_rad": float(r["std"]) if estimated else np.nan,
                "u_between_deg": u_b,
                "u_model_deg": u_m,
                "U_deg": k * u_c,
                "dof": dof,
                "k": k,
                "status": status,
            }
        )
    return pd.DataFrame(rows, columns=OFFSET_COLUMNS)


def loop_offsets(joint_names, report: LoopReport) -> pd.DataFrame:
    """`controller_offsets` of the loop-closed model from its loop closure's report."""
    return controller_offsets(
        joint_names, report.parameters, "loop", report.between_design["loop"], report.model_error_share
    )


def not_determined(row) -> str:
    """A parameter row's status, "not determined" where it is estimated but its posterior is its
    prior's (the loop refit's `prior_dominated`): a U the prior sets is no measurement, so the
    correction carries no U and the status names what the data do determine."""
    status = str(row["status"])
    if status != "estimated" or not bool(row.get("prior_dominated", False)):
        return status
    ratio = float(row.get("posterior_to_prior_std", np.nan))
    share = float(row.get("prior_share", np.nan))
    combination = str(row.get("determined_combination") or "")
    determined = f"; the data determine {combination}" if combination else ""
    why = f"its posterior std is {ratio:.2f} of its prior's"
    if not ratio > PRIOR_DOMINATED and share > 0:  # its own prior is wide: the priors it trades against set it
        own = f" (its std {ratio:.2f} of its own prior's)" if np.isfinite(ratio) else " (it has no prior of its own)"
        why = f"the priors set {share:.0%} of its posterior variance{own}"
    return f"not determined: {why}{determined}"


@dataclass(frozen=True, eq=False)
class CalibratedFiles:
    """paper_urdf, loop_urdf: URDF text; effects: loop_effects.yaml content; offsets: the
    controller offsets of both models (`OFFSET_COLUMNS`)."""

    paper_urdf: str
    loop_urdf: str
    effects: dict
    offsets: pd.DataFrame


def calibrated_stage(
    campaign: Campaign, sensor: str, summary: pd.DataFrame, loop_report: LoopReport, label: str = ""
) -> CalibratedFiles:
    """The calibrated URDFs of the paper's and the loop-closed model of one sensor of a campaign,
    the loop's effects a URDF cannot hold, and both models' controller offsets. summary: the fit's
    summary.csv; loop_report: loop_closure.json."""
    chain = campaign.chain
    paper, loop = paper_calibration(summary, label=label), loop_calibration(loop_report, label=label)
    table = loop_report.parameters
    paper_urdf, _ = calibrated_urdf(chain, paper.values)
    loop_urdf, left = calibrated_urdf(chain, loop.values)
    gp = loop_report.residual_gp or {}
    extra = {
        "campaign": campaign.name,
        "sensor": sensor,
        "robot": dict(campaign.robot).get("serial", ""),
        "effects_added": list(loop_report.effects_added),
        "urdf_source": "the campaign's URDF" if chain.urdf_xml is not None else "generated from the DH table",
        "residual_gp": (
            "not in the URDF: its training rows are loop_closure/residual_gp.parquet, its "
            "hyperparameters loop_closure.json residual_gp"
            if gp.get("added")
            else "not added"
        ),
    }
    between = loop_report.between_design
    offsets = pd.concat(
        [
            controller_offsets(chain.joint_names, summary, "paper", between["paper"]),
            loop_offsets(chain.joint_names, loop_report),
        ],
        ignore_index=True,
    )
    return CalibratedFiles(paper_urdf, loop_urdf, effects_yaml(loop, table, left, extra), offsets)


def calibrated_dh_tables(
    campaign: Campaign, sensor: str, summary: pd.DataFrame, loop_report: LoopReport, label: str = ""
) -> dict[str, dict]:
    """{'paper', 'loop': calibrated DH table} of a campaign given as a DH table
    (`dh_table.calibrated_dh`, checked at every configuration of the sensor's rows), each in the form
    of campaign.yaml's robot/dh with what it holds and how exactly."""
    if "dh" not in campaign.robot:
        raise InputError(
            "the campaign gives no DH table (robot/dh): no calibrated DH table to write",
            file=f"{campaign.name}/campaign.yaml",
            key="robot/dh",
        )
    out = {}
    for calibration in (paper_calibration(summary, label=label), loop_calibration(loop_report, label=label)):
        table = dh_table.calibrated_dh(
            campaign.chain, campaign.robot["dh"], calibration.values, campaign.sensors[sensor].q()
        )
        out[calibration.model] = {
            "campaign": campaign.name,
            "sensor": sensor,
            "model": calibration.model,
            "convention_note": SIGN + "; here it is already in theta",
            **table,
            "holds": "zero-offsets (theta) and link geometry (a, alpha, d, flange); the "
            "loop-closed model's other effects are in loop_effects.yaml",
        }
    return out


def ur_form(campaign: Campaign) -> bool:
    """Whether a campaign gets Universal Robots' kinematics_config: a six-row DH table (a UR arm is
    given as its controller's DH table), whose joints all turn about z (`ur_kinematics.applies`)."""
    dh = campaign.robot.get("dh") if isinstance(campaign.robot, Mapping) else None
    return bool(dh) and len(dh.get("rows", ())) == 6 and ur_kinematics.applies(campaign.chain)


def calibrated_ur_configs(
    campaign: Campaign, sensor: str, summary: pd.DataFrame, loop_report: LoopReport, label: str = ""
) -> dict[str, dict]:
    """{'paper', 'loop': kinematics_config} of a UR campaign (`ur_kinematics.kinematics_config`),
    with what each cannot hold at the sensor's configurations."""
    data = campaign.sensors[sensor]
    return {
        c.model: ur_kinematics.kinematics_config(
            campaign.chain, c.values, data.q(), data.marker, f"{campaign.name}/{sensor}, {c.model} model"
        )
        for c in (paper_calibration(summary, label=label), loop_calibration(loop_report, label=label))
    }


FILES = {
    "paper.urdf": "the paper's model: zero-offsets in the joint origins",
    "loop.urdf": "the loop-closed model: zero-offsets and link geometry in the joint origins (with loop_effects.yaml)",
    "rigid.urdf": "the URDF nearest the loop-closed model near the measured configurations, for tools that load "
    "a URDF alone (its distance from the loop model in workspace.json's urdfs and the certificate)",
    "ik.urdf": "the same fit with only the zero-offsets, base and tool free: a closed-form IK solver stays exact on it",
    "loop_effects.yaml": "the loop-closed model's effects a URDF cannot hold",
    "controller_offsets.csv": "zero-offset corrections for the controller, both models",
}
DH_FILES = {
    "paper_dh.yaml": "the paper's model as the campaign's DH table (robot/dh form)",
    "loop_dh.yaml": "the loop-closed model as the campaign's DH table (robot/dh form), exact or not",
}


def offsets_table(offsets: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """One campaign's controller offsets, every sensor ({sensor: `OFFSET_COLUMNS` frame}), display
    columns: Sensor, Model, Joint, Correction (deg), Std (deg), 95 % interval (deg), u_between (deg),
    u_model (deg), U(Correction) (deg) with its dof and k, Correction (rad), Status."""
    frames = [
        pd.DataFrame(
            {
                "Sensor": sensor,
                "Model": f["model"],
                "Joint": f["joint"],
                "Correction (deg)": f["correction_deg"],
                "Std (deg)": f["std_deg"],
                "2.5% (deg)": f["q2.5_deg"],
                "97.5% (deg)": f["q97.5_deg"],
                "u_between (deg)": f["u_between_deg"],
                "u_model (deg)": f.get("u_model_deg", np.nan),  # absent in files written before it existed
                "U(Correction) (deg)": f["U_deg"],
                "dof": f["dof"],
                "k": f["k"],
                "Correction (rad)": f["correction_rad"],
                "Status": f["status"],
            }
        )
        for sensor, f in offsets.items()
    ]
    return pd.concat(frames, ignore_index=True)


UR_FILES = {
    "paper_ur_kinematics.yaml": "the paper's model as ur_description's kinematics_config (UR ROS driver)",
    "loop_ur_kinematics.yaml": "the loop-closed model's zero-offsets and link geometry as ur_description's "
    "kinematics_config, with what it cannot hold",
}


def files_table(campaign: str, sensors, dh: bool = False, ur: bool = False) -> pd.DataFrame:
    """Sensor, File (path from the results folder, where report.html is), What: the calibrated files
    (with the DH tables when the campaign gives one, and the kinematics_configs of a UR)."""
    files = {**FILES, **(DH_FILES if dh else {}), **(UR_FILES if ur else {})}
    return pd.DataFrame(
        [
            {"Sensor": s, "File": f"{campaign}/{s}/calibrated/{name}", "What": what}
            for s in sensors
            for name, what in files.items()
        ]
    )
