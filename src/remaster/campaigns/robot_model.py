"""A campaign's robot model: the kinematic chain its campaign.yaml `robot` section describes (a URDF,
a DH table, or both checked against each other), and the robot files it refers to.

Here rather than beside `remaster.robot`: the section is a campaign's (checked by
`campaign.validate_robot`), and the robot package sits below the campaigns in the library's layers.
"""

from __future__ import annotations

import functools
import math
import types
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, KinematicsError, quoted
from ..files import read_text, read_yaml
from ..layout import CAMPAIGN_FILE, SHARED_ROBOTS
from ..robot.kinematics import KinematicChain, chain_from_dh, chain_from_urdf, max_chain_difference
from .campaign import validate_robot

CHAIN_CHECK_SEED = 20180612
CHAIN_CHECK_CONFIGURATIONS = 16
CHAIN_TOLERANCE = 1e-6  # m (and rad at a 1 m lever arm)


def urdf_candidates(urdf: str, folder: Path, repo_root: Path) -> list[Path]:
    """Where a campaign's `robot/urdf` may live, in the order they are tried: relative to its
    folder, to the repository root, then as repo_root/SHARED_ROBOTS/<file name>."""
    candidates = [folder / urdf, repo_root / urdf, repo_root / SHARED_ROBOTS / Path(urdf).name]
    return list(dict.fromkeys(candidates))


def robot_section(folder: str | Path) -> Mapping:
    """campaign.yaml's `robot` section as written, for planning a workflow before the campaign is
    read; {} when it does not parse (reading the campaign says why, with file and key). Read
    again only when the file changed: planning a workflow asks for it a hundred times."""
    path = Path(folder) / CAMPAIGN_FILE
    try:
        stat = path.stat()
    except OSError:
        return {}
    return _robot_section_of(str(path), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=256)
def _robot_section_of(path: str, modified_ns: int, size: int) -> Mapping:
    """The `robot` section of the campaign.yaml at `path` as it was at (modified_ns, size), read-only."""
    try:
        robot = read_yaml(path).get("robot")
    except (OSError, InputError, AttributeError):
        return {}
    return types.MappingProxyType(robot) if isinstance(robot, Mapping) else {}


def robot_files(folder: str | Path, repo_root: str | Path = ".") -> list[Path]:
    """The robot description files a campaign folder's campaign.yaml refers to outside the folder
    (its URDF, found as `load_chain` finds it), so that a workflow can declare and hash them; []
    when there are none or campaign.yaml does not parse (reading the campaign says why)."""
    folder = Path(folder)
    urdf = robot_section(folder).get("urdf")
    if not isinstance(urdf, str):
        return []
    found = next((p for p in urdf_candidates(urdf, folder, Path(repo_root)) if p.is_file()), None)
    return [] if found is None or found.resolve().parent == folder.resolve() else [found]


def _in_robot_section(exc: KinematicsError, source: str, note: str = "") -> KinematicsError:
    """The same problem, reported against campaign.yaml's robot/<key>."""
    key = f"robot/{exc.key}" if exc.key else "robot"
    return KinematicsError(exc.reason + note, file=source, key=key, rows=exc.rows)


def load_chain(
    robot_meta: Mapping[str, Any],
    folder: str | Path,
    repo_root: str | Path | None = None,
    *,
    source: str | None = None,
    name: str = "dh_robot",
) -> KinematicChain:
    """The kinematic chain of a campaign's `robot` section.

    `urdf` is looked for as `urdf_candidates` says (repo_root default: the current directory);
    `base`/`flange` are its links. `dh` builds a chain from DH rows (named `name`). When both are
    given they must agree to CHAIN_TOLERANCE on the flange pose over fixed-seed random
    configurations within +-pi; the URDF chain (joint names, limits, masses) is returned.
    `source` names campaign.yaml in errors.
    """
    folder = Path(folder)
    repo_root = Path.cwd() if repo_root is None else Path(repo_root)
    source = str(folder / CAMPAIGN_FILE) if source is None else source
    robot = validate_robot(robot_meta, source)

    urdf_chain = dh_chain = None
    if "urdf" in robot:
        candidates = urdf_candidates(robot["urdf"], folder, repo_root)
        # a directory or a symlink (a loop, a dangling one) in the URDF's place is named by the reader
        # rather than passed over as "not found"
        urdf_path = next((p for p in candidates if p.is_file() or p.is_dir() or p.is_symlink()), None)
        if urdf_path is None:
            raise KinematicsError(
                f"URDF file {quoted(robot['urdf'])} not found (looked for {', '.join(str(p) for p in candidates)})",
                file=source,
                key="robot/urdf",
            )
        try:
            urdf_chain = chain_from_urdf(
                read_text(urdf_path), robot.get("base"), robot.get("flange"), source=str(urdf_path)
            )
        except KinematicsError as exc:
            if exc.key not in ("base", "flange"):
                raise
            raise _in_robot_section(exc, source, f" (URDF {urdf_path})") from None
    if "dh" in robot:
        dh = robot["dh"]
        try:
            dh_chain = chain_from_dh(dh["rows"], dh["convention"], dh.get("flange"), name=name, source=source)
        except KinematicsError as exc:
            raise _in_robot_section(exc, source) from None
    if urdf_chain is None or dh_chain is None:
        return urdf_chain or dh_chain

    if urdf_chain.n_joints != dh_chain.n_joints:
        raise KinematicsError(
            f"urdf and dh describe different robots: the URDF chain has {urdf_chain.n_joints} "
            f"joints, the DH table {dh_chain.n_joints} rows",
            file=source,
            key="robot",
        )
    rng = np.random.default_rng(CHAIN_CHECK_SEED)
    q = rng.uniform(-math.pi, math.pi, size=(CHAIN_CHECK_CONFIGURATIONS, urdf_chain.n_joints))
    difference = max_chain_difference(urdf_chain, dh_chain, q)
    if not difference <= CHAIN_TOLERANCE:
        raise KinematicsError(
            f"urdf and dh describe different chains: flange poses differ by up to "
            f"{difference * 1e3:.4g} mm (tolerance {CHAIN_TOLERANCE * 1e3:g} mm)",
            file=source,
            key="robot",
        )
    return urdf_chain
