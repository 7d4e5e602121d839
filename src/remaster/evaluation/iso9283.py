"""ISO 9283 pose characteristics where a campaign's design allows them.

ISO 9283 (manipulating industrial robots: performance criteria and test methods) characterises a
pose by n cycles to the same command: with e_j the attained minus the commanded position of cycle
j (here measured minus predicted, in the sensor frame through the registration),

- position accuracy AP = || mean_j e_j ||, the distance from the command to the cycles' barycentre;
- position repeatability RP = l_bar + 3 S_l, l_j = || e_j - mean e ||, S_l their std (n - 1).

RP needs a configuration commanded more than once (ISO asks for 30 cycles); AP is given over each
measured configuration's cycles (one cycle when nothing repeats, which makes it that
configuration's post-registration error). What a campaign of static single-point measurements
cannot give is said, not left out: orientation accuracy and repeatability (one marker point, no
tool orientation), path, distance and stabilisation characteristics (static poses only).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..campaigns.campaign import SensorData
from ..evaluation.accuracy import REGISTRATION_AS_FITTED, VERNIER_LEAST_SQUARES
from ..labels import sensor_label
from ..loop.noise_floor import configuration_groups
from ..robot.kinematics import KinematicChain, flange_poses
from ..robot.planning import ISO9283_PLANE_CORNERS
from ..units import MM

CANNOT_GIVE = (
    "orientation accuracy and repeatability (AP_a,b,c, RP_a,b,c): one marker point, not the tool's "
    "orientation, is measured; path, distance, cornering and stabilisation characteristics (AT, RT, AD, "
    "RD, ...): static poses only"
)
MODELS = ((VERNIER_LEAST_SQUARES, "controller's zero-offsets"), ("Bayesian", "remastered zero-offsets"))


def pose_characteristics(residuals, groups) -> pd.DataFrame:
    """Per configuration group: cycles, APx, APy, APz (m, the barycentre's offset from the command
    per axis), AP (m) and RP (m; NaN with one cycle). residuals (n, 3) m attained minus commanded;
    groups (n,) integer labels of the configuration each row commands."""
    residuals, groups = np.asarray(residuals, dtype=float), np.asarray(groups)
    labels, group_of, cycles = np.unique(groups, return_inverse=True, return_counts=True)
    # every group at once (a campaign of a million distinct configurations has as many groups)
    centre = np.stack([np.bincount(group_of, weights=residuals[:, a], minlength=len(labels)) for a in range(3)], 1)
    centre /= cycles[:, None]
    spread = np.linalg.norm(residuals - centre[group_of], axis=1)
    mean_spread = np.bincount(group_of, weights=spread, minlength=len(labels)) / cycles
    squares = np.bincount(group_of, weights=(spread - mean_spread[group_of]) ** 2, minlength=len(labels))
    with np.errstate(invalid="ignore", divide="ignore"):
        rp = np.where(cycles > 1, mean_spread + 3.0 * np.sqrt(squares / (cycles - 1)), np.nan)
    return pd.DataFrame(
        {
            "group": labels,
            "cycles": cycles,
            "APx": centre[:, 0],
            "APy": centre[:, 1],
            "APz": centre[:, 2],
            "AP": np.linalg.norm(centre, axis=1),
            "RP": rp,
        },
        columns=["group", "cycles", "APx", "APy", "APz", "AP", "RP"],
    )


def _validation_poses(data: SensorData, frame: pd.DataFrame, method: str) -> tuple[pd.DataFrame, np.ndarray]:
    """(`pose_characteristics` of one model's validation rows, each row's configuration group)."""
    group, _ = configuration_groups(data.table[list(data.joint_columns)].to_numpy(float))
    part = frame[
        (frame["set"] == "validation") & (frame["method"] == method) & (frame["registration"] == REGISTRATION_AS_FITTED)
    ]
    rows = part["row"].to_numpy(int)
    residuals = part[["residual_x_mm", "residual_y_mm", "residual_z_mm"]].to_numpy(float) * MM
    poses = pose_characteristics(residuals, group[rows])
    _, first = np.unique(group[rows], return_index=True)  # in the order of poses' groups: sorted labels
    return poses.assign(first_row=rows[first].astype(int)), group


ISO_POSES = ("P1", "P2", "P3", "P4", "P5")
CUBE_TOLERANCE = 0.05  # of the cube's half-diagonal offset: how far the five points may be off the pattern


def iso_pose_names(chain: KinematicChain, q) -> list[str] | None:
    """ISO 9283's names P1..P5 of five configurations q (5, N) rad when their flange positions
    (nominal forward kinematics, base frame) are the standard's five points of a cube with edges
    along the base axes, as `remaster plan --objective iso9283` places them
    (`planning.iso9283_points`): P1 the cube's centre (the mean of the five); P2..P5 on the
    diagonals of the diagonal plane through the cube's lower -x edge and upper +x edge, named as
    `planning.iso9283_points` numbers them (the mapping used here, the planner's: P2 towards
    (-x, -y, -z), P3 towards (-x, +y, -z), P4 towards (+x, +y, +z), P5 towards (+x, -y, +z) from
    the centre; base-frame axes, so a cube turned about the base is not recognised).
    None when they are not such points (another design, or not five): the table then names no
    ISO pose rather than guess."""
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or len(q) != len(ISO_POSES):
        return None
    points = flange_poses(chain, q)[:, :3, 3]
    offsets = points - points.mean(axis=0)
    distance = np.linalg.norm(offsets, axis=1)
    centre = int(np.argmin(distance))
    reach = np.delete(offsets, centre, axis=0)
    half = np.abs(reach).mean()  # the corners' offset along each axis
    if half <= 0 or distance[centre] > CUBE_TOLERANCE * half:
        return None
    names = [""] * len(ISO_POSES)
    names[centre] = ISO_POSES[0]
    for index, offset in zip(np.delete(np.arange(len(ISO_POSES)), centre), reach):
        corner = np.flatnonzero(np.all(np.abs(offset / half - ISO9283_PLANE_CORNERS) < CUBE_TOLERANCE * 4, axis=1))
        if corner.size != 1 or ISO_POSES[1 + corner[0]] in names:
            return None
        names[index] = ISO_POSES[1 + corner[0]]
    return names


def iso9283_poses_table(
    sensors: dict[str, SensorData], errors: dict[str, pd.DataFrame], chain: KinematicChain | None = None
) -> pd.DataFrame:
    """ISO 9283's per-pose report: per sensor, model and configuration of the validation set measured
    more than once, cycles, APx, APy, APz, AP and RP (mm), with the configuration's first table row
    and plan pose; one row saying so per sensor and model when no configuration repeats. Arguments
    as `iso9283_table`'s, and the campaign's `chain`.

    When the repeated configurations are the five points of an ISO 9283 cube (`iso_pose_names`,
    with `chain`), each row names its pose P1..P5 (column "ISO pose") and the rows are in that
    order; otherwise the column is empty and the rows are in the order the validation set first
    measured each configuration (the plan's order)."""
    out = []
    for sensor, data in sensors.items():
        for method, label in MODELS:
            poses, _ = _validation_poses(data, errors[sensor], method)
            repeated = poses[poses["cycles"] > 1].sort_values("first_row", kind="stable")
            names = None
            if chain is not None and len(repeated):
                q = data.table[list(data.joint_columns)].to_numpy(float)[repeated["first_row"].to_numpy(int)]
                names = iso_pose_names(chain, q)
            if names is not None:
                repeated = repeated.assign(iso_pose=names).sort_values("iso_pose", kind="stable")
            else:
                repeated = repeated.assign(iso_pose="")
            if repeated.empty:
                out.append(
                    {
                        "Sensor": sensor_label(sensor),
                        "Model": label,
                        "note": "no configuration is measured more than once: ISO 9283 asks for 30 cycles to each pose",
                    }
                )
            for _, pose in repeated.iterrows():
                row = int(pose["first_row"])
                out.append(
                    {
                        "Sensor": sensor_label(sensor),
                        "Model": label,
                        "ISO pose": pose["iso_pose"],
                        "first row": row,
                        "plan pose": int(data.table["pose"].iloc[row]) if "pose" in data.table else np.nan,
                        "cycles": int(pose["cycles"]),
                        **{f"AP{a} (mm)": pose[f"AP{a}"] / MM for a in ("x", "y", "z", "")},
                        "RP (mm)": pose["RP"] / MM,
                        "note": "",
                    }
                )
    columns = ["Sensor", "Model", "ISO pose", "first row", "plan pose", "cycles"]
    columns += [f"AP{a} (mm)" for a in ("x", "y", "z", "")] + ["RP (mm)", "note"]
    return pd.DataFrame(out, columns=columns)


def iso9283_table(sensors: dict[str, SensorData], errors: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per sensor and model (controller's and remastered zero-offsets): AP and RP (mm) over the
    validation set's configurations with the optimization set's registration, pooled: the mean and
    the worst over configurations (the per-pose report is `iso9283_poses_table`), and what the
    design cannot give.

    sensors: name -> the campaign's sensor data (its table's rows are the errors' rows); errors:
    name -> `metrics/configuration_errors.csv` (row, set, registration, method, residual_{x,y,z}_mm)."""
    out = []
    for sensor, data in sensors.items():
        for method, label in MODELS:
            poses, _ = _validation_poses(data, errors[sensor], method)
            repeated = poses[poses["cycles"] > 1]
            note = (
                f"RP from {len(repeated)} configurations measured {int(repeated['cycles'].min())} to "
                f"{int(repeated['cycles'].max())} times (ISO 9283 asks for 30 cycles)"
                if len(repeated)
                else "RP not available: no configuration is measured more than once (ISO 9283 asks for 30 cycles "
                "to one command)"
            )
            out.append(
                {
                    "Sensor": sensor_label(sensor),
                    "Model": label,
                    "configurations": len(poses),
                    "cycles": int(poses["cycles"].sum()),
                    "AP mean (mm)": poses["AP"].mean() / MM,
                    "AP max (mm)": poses["AP"].max() / MM,
                    "RP mean (mm)": repeated["RP"].mean() / MM if len(repeated) else np.nan,
                    "RP max (mm)": repeated["RP"].max() / MM if len(repeated) else np.nan,
                    "note": note,
                }
            )
    return pd.DataFrame(out)
