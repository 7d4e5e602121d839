"""Which robot a campaign is of: the identity key that campaigns of one robot model share, and its
file-name-safe slug (used by every stage that seeds a generator or names a file per robot)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import PurePosixPath
from typing import Any

import numpy as np

from .errors import InputError

DH_DIGITS = 9  # DH values are rounded to 1e-9 (m, rad) before they are hashed


def _robot_section(campaign: Any) -> Mapping[str, Any]:
    robot = getattr(campaign, "robot", None)  # a remaster.campaigns.campaign.Campaign
    if robot is None and isinstance(campaign, Mapping):
        robot = campaign.get("robot", campaign)  # campaign.yaml / summary.json content, or the section itself
    if not isinstance(robot, Mapping):
        raise InputError(f"no robot section in {type(campaign).__name__}", key="robot")
    return robot


def _rounded(values) -> list:
    """Nested numbers rounded to DH_DIGITS, -0.0 as 0.0."""
    if isinstance(values, (list, tuple, np.ndarray)):
        return [_rounded(v) for v in values]
    return round(float(values), DH_DIGITS) + 0.0


def robot_identity(campaign: Any) -> str:
    """A key equal for campaigns of the same robot model (the same kinematic chain).

    `campaign`: a `Campaign`, campaign.yaml's content, its `robot` section, or the summary.json
    `campaign.summarize` writes. The key:
    - URDF: 'urdf:<file name>:<base>:<flange>' (directory dropped: kuka-twin and kuka-twin-2019
      both give 'urdf:kuka_iiwa14.urdf:iiwa_link_0:iiwa_link_ee'; base/flange empty when not given);
      used also when a DH table is given beside the URDF, as the reader checks they agree;
    - DH only: 'dh:<convention>:<12 hex>', a SHA-256 of the rows and flange rounded to 1e-9;
    - a campaign summary (no urdf/dh, the chain's name, joints and frames):
      'chain:<name>:<base>:<flange>:<n> joints'. This form never equals the others, and a DH chain
      is named after its campaign there: compare campaigns from the same kind of input,
      preferably campaign.yaml.
    Two campaign-local URDFs of the same file name are taken for the same model; the key names the
    model, not the physical unit, unless the robot section gives the unit's `serial`: then the key
    is 'serial:<serial>', and only campaigns of that very robot are compared.
    """
    robot = _robot_section(campaign)
    if robot.get("serial"):
        return f"serial:{robot['serial']}"
    if robot.get("urdf"):
        name = PurePosixPath(str(robot["urdf"]).replace("\\", "/")).name
        return f"urdf:{name}:{robot.get('base') or ''}:{robot.get('flange') or ''}"
    if robot.get("dh"):
        dh = robot["dh"]
        content = {
            "convention": dh.get("convention", "standard"),
            "rows": _rounded(dh["rows"]),
            "flange": None if dh.get("flange") is None else _rounded(dh["flange"]),
        }
        digest = hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:12]
        return f"dh:{content['convention']}:{digest}"
    if robot.get("joints"):
        return (
            f"chain:{robot.get('name', '')}:{robot.get('base') or ''}:{robot.get('flange') or ''}:"
            f"{len(robot['joints'])} joints"
        )
    raise InputError("names no robot model (urdf or dh, or a summary's chain)", key="robot")


def robot_slug(identity: str) -> str:
    """A file-name-safe short form of a robot identity."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in identity)[:80]
