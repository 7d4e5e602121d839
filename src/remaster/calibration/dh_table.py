"""The calibrated DH table of a campaign given as a DH table: the calibrated model's zero-offsets and
link geometry written as DH rows of the campaign's own convention, for a controller or a tool that
takes DH parameters rather than a URDF.

**Same bodies, other frames.** remaster's chain (the URDF's when a campaign gives both) has a body
frame B_j after each joint j; the DH chain has a frame D_j on the same body, D_j = B_j G_j, with G_j
fixed, turning z onto joint j's axis (so Rot(a_j, q) G_j = G_j Rz(q)); nominally
G_j = B_j(0)^-1 D_j(0), and G_0 = I (both start at the base). With the calibrated fixed transforms
F'_j (link geometry, and the zero-offset Rot(a_j, d_j) folded in, as in the calibrated URDF):

    F^DH_j = G_{j-1}^-1 F'_j G_j,        F^DH_tool = G_N^-1 F'_tool,

each then factored into the convention's form. Standard: F^DH_1 = Rz(theta_1), F^DH_j =
Tz(d_{j-1}) Tx(a_{j-1}) Rx(alpha_{j-1}) Rz(theta_j), F^DH_tool = Tz(d_N) Tx(a_N) Rx(alpha_N) flange.
Modified (Craig): F^DH_j = Tz(d_{j-1}) Tx(a_j) Rx(alpha_j) Rz(theta_j) (d_0 = 0), F^DH_tool = Tz(d_N)
flange.

**Exact and not.** A zero-offset always lands in theta and a length error in a and d. A twist lands in
alpha only when it follows a theta of 0 or pi (as in the UR's table); after any other theta, or on the
first joint of a standard table (which has no base transform), it tilts an axis in a way DH cannot
express (Hayati's beta would). The tool's errors always fit: what the last row cannot hold goes into
the flange. Where a transform is not of DH form, the nearest DH row is written and the table says so,
with how far its forward kinematics is from the calibrated model's at the campaign's configurations.

SI inside (m, rad); the change from the nominal table in mm and deg.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from .. import spatial
from ..errors import KinematicsError
from ..inference.parameter_blocks import calibrated_transforms
from ..robot.kinematics import KinematicChain, chain_from_dh, flange_poses
from ..units import DEG, MM

EXACT = 1e-10  # m and rad: below this a transform is of DH form (products of 4x4 matrices, not a fit)


def _body_frames(joint_transforms) -> np.ndarray:
    """B_0..B_N (N + 1, 4, 4) at q = 0."""
    frames = [np.eye(4)]
    for transform in joint_transforms:
        frames.append(frames[-1] @ transform)
    return np.array(frames)


def _dh_transform(d, a, alpha, theta) -> np.ndarray:
    """Tz(d) Tx(a) Rx(alpha) Rz(theta)."""
    return spatial.homogeneous(spatial.rot_x(alpha) @ spatial.rot_z(theta), np.array([a, 0.0, d]))


def _factor(transform, free: str = "d a alpha theta") -> tuple[dict[str, float], float]:
    """({d, a, alpha, theta}, miss): the transform as Tz(d) Tx(a) Rx(alpha) Rz(theta), only the
    `free` ones non-zero; miss = translation miss (m) + rotation miss (rad) of that nearest form,
    0 (to rounding) when the transform is of that form."""
    t, rotation = transform[:3, 3], transform[:3, :3]
    out = {"d": t[2] if "d" in free else 0.0, "a": t[0] if "a" in free else 0.0}
    out["alpha"] = float(np.arctan2(-rotation[1, 2], rotation[2, 2])) if "alpha" in free else 0.0
    rest = spatial.rot_x(out["alpha"]).T @ rotation
    out["theta"] = float(np.arctan2(rest[1, 0], rest[0, 0])) if "theta" in free else 0.0
    out = {k: float(v) for k, v in out.items()}
    nearest = _dh_transform(**out)
    miss = np.linalg.norm(nearest[:3, 3] - t) + abs(spatial.rotation_angle(nearest[:3, :3].T @ rotation))
    return out, float(miss)


def _frame_change(chain: KinematicChain, dh: KinematicChain) -> np.ndarray:
    """G_0..G_N (N + 1, 4, 4) from the chain's body frames to the DH chain's (module docstring)."""
    change = np.linalg.inv(_body_frames(chain.joint_transforms)) @ _body_frames(dh.joint_transforms)
    for j in range(1, chain.n_joints + 1):
        axis = chain.joint_axes[j - 1]
        turned, shift = change[j, :3, 2], change[j, :3, 3]
        if not (np.allclose(turned, axis, atol=1e-9) and np.linalg.norm(np.cross(shift, axis)) < 1e-9):
            raise KinematicsError(
                f"the DH table's joint {j} is not on the URDF's joint axis: they are not the same chain", key="robot/dh"
            )
    return change


LEVER = 1.0  # m: an orientation difference counted as a position difference at this lever arm
# m and rad: a table fitted by least squares that reproduces the calibrated model to this at every
# configuration holds it (the least squares' own tolerance; 1e-9 m is far below any sensor's noise)
FITTED_EXACT = 1e-9


def _nearest_table(rows, convention: str, flange, expected, configurations) -> np.ndarray:
    """DH rows (N, 4) whose flange poses are nearest `expected` (n, 4, 4) at `configurations`
    (n, N), by least squares from `rows`: positions, and orientations at LEVER. Where a calibrated
    transform is not of DH form (a tilt between parallel axes, a shift DH has no parameter for)
    no table holds it, and the rows nearest transform by transform leave errors that a joint's
    other rows could take up; this finds that table. The first row's theta stays: a standard
    table's base has no transform, so joint 1's theta is its zero-offset, which the rows must not
    trade against the base frame."""
    import scipy.optimize

    def residual(x):
        table = rows.copy()
        table.ravel()[free] = x
        got = flange_poses(chain_from_dh(table, convention, flange), configurations)
        return np.concatenate(
            [(got[:, :3, 3] - expected[:, :3, 3]).ravel(), LEVER * (got[:, :3, :3] - expected[:, :3, :3]).ravel()]
        )

    free = np.ones(rows.size, dtype=bool)
    free[3] = False
    scale = np.tile([MM, DEG, MM, DEG], len(rows))[free]
    # Levenberg-Marquardt (MINPACK): the trust region's SVD of the whole Jacobian at every step made
    # this the main job's slowest fit (the bundled UR5's loop model on its 1,000 configurations: 4.6
    # times the time, the same table to 2.3e-8; benchmarks/bench_dh_table.py: 1.6-2.5 times). Where
    # the rows have a direction the flange poses do not see, the two may end at different points of
    # it that reproduce the calibrated model equally
    fit = scipy.optimize.least_squares(residual, rows.ravel()[free], x_scale=scale, method="lm")
    out = rows.copy()
    out.ravel()[free] = fit.x
    return out


def calibrated_dh(chain: KinematicChain, dh: Mapping, values: Mapping[str, float], configurations) -> dict:
    """The calibrated DH table of `values` {parameter: SI}, in the form of campaign.yaml's robot/dh
    (`dh`: convention, rows [a, alpha, d, theta], optional flange), plus: exact (every transform of DH
    form), not_dh_form (which are not, and the nearest DH row written instead), the largest flange
    position (m) and orientation (rad) difference from the calibrated model over `configurations`
    (n, N), and the change from the nominal table in mm and deg."""
    convention, nominal = dh["convention"], np.asarray(dh["rows"], dtype=float)
    flange = np.eye(4) if dh.get("flange") is None else np.asarray(dh["flange"], dtype=float)
    nominal_chain = chain_from_dh(nominal, convention, flange)
    change = _frame_change(chain, nominal_chain)
    joints, tool = calibrated_transforms(chain, values)
    transforms = np.linalg.inv(change[:-1]) @ joints @ change[1:]
    dh_tool = np.linalg.inv(change[-1]) @ tool
    n = chain.n_joints
    rows = nominal.copy()
    misses = []
    for j in range(n):
        standard = convention == "standard"
        first = "theta" if standard else "a alpha theta"  # a standard table has no base transform
        free = first if j == 0 else "d a alpha theta"
        part, miss = _factor(transforms[j], free)
        if miss > EXACT:
            why = (
                "joint 1's axis tilted from the base's z, which a standard table without a base transform cannot hold"
                if standard and j == 0
                else f"a tilt or shift DH has no parameter for (a twist after a theta of {part['theta'] / DEG:.4g} deg, "
                "neither 0 nor 180, or a shift along the previous y axis)"
            )
            misses.append(f"F{j + 1}: {why}; nearest DH row alone misses by {miss:.3g} m + rad")
        rows[j, 3] = part["theta"]
        if standard:
            if j > 0:
                rows[j - 1, :3] = part["a"], part["alpha"], part["d"]
        else:
            rows[j, :2] = part["a"], part["alpha"]
            if j > 0:
                rows[j - 1, 2] = part["d"]
    last = _factor(dh_tool @ np.linalg.inv(flange), "d a alpha" if convention == "standard" else "d")
    if last[1] <= EXACT:  # the last row holds the tool's errors and the flange stays as given
        rows[-1, 2] = last[0]["d"]
        if convention == "standard":
            rows[-1, :2] = last[0]["a"], last[0]["alpha"]
    else:  # the last row stays nominal and the flange takes the rest, which is always exact
        kept = dict(zip(("a", "alpha", "d"), nominal[-1, :3]))
        if convention != "standard":
            kept["a"] = kept["alpha"] = 0.0
        flange = np.linalg.inv(_dh_transform(kept["d"], kept["a"], kept["alpha"], 0.0)) @ dh_tool
    expected = flange_poses(replace(chain, joint_transforms=joints, tool_transform=tool), configurations)
    if misses:  # the nearest rows, transform by transform, then the table nearest the calibrated model
        rows = _nearest_table(rows, convention, flange, expected, configurations)
    got = flange_poses(chain_from_dh(rows, convention, flange), configurations)
    position = float(np.max(np.linalg.norm(got[:, :3, 3] - expected[:, :3, 3], axis=1)))
    orientation = max(spatial.rotation_angle(g[:3, :3].T @ e[:3, :3]) for g, e in zip(got, expected))
    fitted = bool(misses)
    if position < FITTED_EXACT and orientation < FITTED_EXACT:  # the fitted table holds the model after all
        misses = []
    delta = rows - nominal
    delta[:, 3] = np.angle(np.exp(1j * delta[:, 3]))
    return {
        "convention": convention,
        "rows": rows.tolist(),
        "flange": flange.tolist(),
        "exact": not misses,
        "not_dh_form": misses,
        "max_position_difference_m": position,
        "max_orientation_difference_rad": float(orientation),
        "checked_at": f"{len(configurations)} configurations of the campaign",
        "method": "each calibrated transform factored into its DH row"
        + (
            "; not all are of DH form, so the rows are then fitted by least squares to the calibrated model's flange "
            "poses at those configurations (orientation at a 1 m lever)"
            if fitted
            else ""
        ),
        "change_from_nominal": [
            {"a_mm": r[0] / MM, "alpha_deg": r[1] / DEG, "d_mm": r[2] / MM, "theta_deg": r[3] / DEG}
            for r in delta.tolist()
        ],
    }
