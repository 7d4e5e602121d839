"""What a workspace design starts from: the candidate configurations (generated as `remaster plan`
generates them, with every joint free, or given as a table), and, for the next configurations of an
existing campaign, that campaign's information as the prior (docs/planning.md).

Generated candidates pass the checks of `remaster.robot.planning` (joint limits, floor, self-collision,
the marker seen by the sensor): on a 7-axis S-R-S arm, Latin-hypercube poses pointing the tool at the
sensor with every inverse-kinematics branch and joint 3 drawn within its limits for each pose
(`planning.plan_set`, q3 = FREE: the redundant configurations are candidates too), and as many random
joint-space configurations (`planning.plan_random`), which reach the parts of the joint space the
pointing poses never do; on any other arm the random ones alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..calibration.compensation import joint_commands
from ..campaigns.campaign import SensorData
from ..errors import InputError
from ..planning import design_posterior as dp
from ..robot import planning
from ..robot.kinematics import KinematicChain
from ..robot.priors import Priors

DEFAULT_COLLISION = planning.CollisionModel()  # frozen: one instance serves every default


def generated_candidates(
    chain: KinematicChain,
    sensor_origin,
    marker,
    rng: np.random.Generator,
    *,
    poses: int = 300,
    collision: planning.CollisionModel = DEFAULT_COLLISION,
    set_name: str = "optimization",
) -> pd.DataFrame:
    """Candidate configurations as a plan table (set, pose, solution, q1..qN rad): on a 7-axis S-R-S
    arm, every usable inverse-kinematics solution of `poses` Latin-hypercube poses pointing at
    `sensor_origin` (3,) m with joint 3 free, then `poses` random joint-space configurations (each its
    own pose); on any other arm the random ones alone. Both pass `planning`'s checks; the random ones
    reach the parts of the joint space the pointing poses never do (the workspace is judged there)."""
    sight = planning.SightLine(np.asarray(sensor_origin, dtype=float), np.asarray(marker, dtype=float))
    tables = []
    if chain.n_joints == 7:
        tables.append(
            planning.plan_set(
                chain,
                set_name,
                sight.sensor_origin,
                [sight],
                rng,
                size=planning.SetSize(candidates=poses),
                model=collision,
                q3=planning.FREE,
            ).table
        )
    random = planning.plan_random(chain, set_name, [sight], rng, n_configurations=poses, model=collision).table
    if tables:
        random["pose"] += int(tables[0]["pose"].max()) + 1 if len(tables[0]) else 0
    table = pd.concat([*tables, random], ignore_index=True)
    if table.empty:
        raise InputError(f"no candidate configuration of {poses} poses passes the checks", key="plan")
    return table


def table_candidates(table: pd.DataFrame, chain: KinematicChain, label: str) -> pd.DataFrame:
    """A candidates table (a plan CSV or a campaign's rows: q1..qN in rad, any other columns kept) as
    a plan table: its q columns checked (InputError naming the file, column and rows: missing, not a
    number, beyond the joint limits), set/pose/solution added where missing (pose = row, solution 0)."""
    if table.empty:
        raise InputError("no candidate configurations (the table has no rows)", file=label)
    q = joint_commands(table, chain, label)
    out = table.reset_index(drop=True).copy()
    if "set" not in out.columns:
        out.insert(0, "set", "optimization")
    if "pose" not in out.columns:
        out.insert(1, "pose", np.arange(len(out), dtype=np.int64))
    if "solution" not in out.columns:
        out.insert(2, "solution", np.zeros(len(out), dtype=np.int64))
    for j in range(chain.n_joints):
        out[f"q{j + 1}"] = q[:, j]
    return out


def configurations(table: pd.DataFrame, n_joints: int) -> np.ndarray:
    """(n, N) rad of a plan table's q1..qN."""
    return table[[f"q{j + 1}" for j in range(n_joints)]].to_numpy(dtype=float)


@dataclass(frozen=True, eq=False)
class CampaignPrior:
    """An existing campaign's sensor as the prior of its next configurations: model (the complete
    error model at its registration and fitted noise), information (P, P) display units^-2 (the
    priors plus its measured optimization rows), rows: the table rows counted, moved_fraction (N,):
    each joint's measured range over its range (what the campaign never moved shows as ~0)."""

    model: dp.ErrorModel
    information: np.ndarray
    rows: np.ndarray
    moved_fraction: np.ndarray


def campaign_prior(
    chain: KinematicChain,
    sensor: SensorData,
    t_nr,
    sigma: float,
    priors: Priors,
    held=None,
    exclude=(),
) -> CampaignPrior:
    """The campaign's posterior, linearized: the complete error model at the registration `t_nr`
    (4, 4) with the noise `sigma` (m) its fit found and the parameters its fit held (`held`, default
    the design's own), informed by its measured optimization rows except `exclude` (gross errors)."""
    model = dp.complete_error_model(chain, sensor.marker, t_nr, priors, sigma, held=held)
    rows = np.setdiff1d(sensor.measured_rows("optimization"), np.asarray(exclude, dtype=int))
    q = sensor.table.loc[rows, list(sensor.joint_columns)].to_numpy(dtype=float)
    information = model.prior_information() + dp.information(model.whitened_jacobian(q))
    ranges = np.array([planning.joint_range(chain, j) for j in range(chain.n_joints)])
    moved = np.ptp(q, axis=0) / (ranges[:, 1] - ranges[:, 0]) if len(q) else np.zeros(chain.n_joints)
    return CampaignPrior(model, information, rows, moved)
