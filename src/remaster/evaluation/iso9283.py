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


def iso9283_poses_table(sensors: dict[str, SensorData], errors: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """ISO 9283's per-pose report: per sensor, model and configuration of the validation set measured
    more than once (ISO's poses P1-P5, each over its cycles), cycles, APx, APy, APz, AP and RP (mm),
    with the configuration's first table row and plan pose; one row saying so per sensor and model
    when no configuration repeats. Arguments as `iso9283_table`'s."""
    out = []
    for sensor, data in sensors.items():
        for method, label in MODELS:
            poses, _ = _validation_poses(data, errors[sensor], method)
            repeated = poses[poses["cycles"] > 1]
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
                        "first row": row,
                        "plan pose": int(data.table["pose"].iloc[row]) if "pose" in data.table else np.nan,
                        "cycles": int(pose["cycles"]),
                        **{f"AP{a} (mm)": pose[f"AP{a}"] / MM for a in ("x", "y", "z", "")},
                        "RP (mm)": pose["RP"] / MM,
                        "note": "",
                    }
                )
    columns = ["Sensor", "Model", "first row", "plan pose", "cycles"]
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
