"""The paper's measurement model and its posterior (eqs. point_mod_transf and posterior).

    p_N,i = T*(Theta1) T_NR FK(q_i + Theta2) marker,   E_i = p_ref,i - p_N,i ~ N(0, sigma^2 I3)

Theta1 = registration.{x, y, z, alpha, beta, gamma} corrects the initial sensor <- robot
transform T_NR: T* = Trans(x, y, z) Rz(alpha) Ry(beta) Rx(gamma). Theta2 = zero_offsets.q1..qN
add to the joint readings. With a flat prior on Theta and Jeffreys' on sigma the log-posterior is

    log p(Theta, sigma | data) = -(3n + 2) log sigma - E(Theta) / (2 sigma^2) + const,

E the sum of squared residuals over the n measured points. Parameters are SI (m, rad);
`scale` gives the paper's display units (mm, deg) in SI, which samplers use as step units.

The model itself is the block model without extension blocks (`remaster.inference.blocks.paper_model`);
this module holds the parameter names, display units and the registration's correction transform,
which readers of results use without building a model.
"""

from __future__ import annotations

import numpy as np

from .. import spatial
from ..units import DEG, MM

REGISTRATION = ("x", "y", "z", "alpha", "beta", "gamma")
SIGMA = "noise.sigma"


def parameter_names(n_joints: int) -> tuple[str, ...]:
    """Every model parameter (sigma excluded), registration first."""
    return tuple(f"registration.{p}" for p in REGISTRATION) + tuple(f"zero_offsets.q{j + 1}" for j in range(n_joints))


def display_scale(name: str) -> float:
    """SI size of one display unit of a parameter: 1 mm for lengths, 1 deg for angles."""
    return MM if name in ("registration.x", "registration.y", "registration.z", SIGMA) else DEG


def display_value(name: str, value: float) -> float:
    """A parameter value in its display unit (mm or deg)."""
    return float(value) / display_scale(name)


def display_unit(name: str) -> str:
    """'mm' or 'deg': the display unit of a parameter (`display_scale`)."""
    return "mm" if display_scale(name) == MM else "deg"


def by_parameter(table):
    """A parameter table (a `parameter` column, or already indexed by it) indexed by parameter name."""
    return table.set_index("parameter") if "parameter" in table.columns else table


def correction_transforms(registration) -> np.ndarray:
    """T*(Theta1) (..., 4, 4) for registration parameters (..., 6): Trans(x,y,z) Rz Ry Rx."""
    r = np.asarray(registration, dtype=float)
    rotation = spatial.euler_zyx_to_matrix(r[..., 3], r[..., 4], r[..., 5])
    return spatial.homogeneous(rotation, r[..., :3])


def correction_parameters(transform) -> np.ndarray:
    """The inverse of `correction_transforms`: (..., 6) (x, y, z m; alpha, beta, gamma rad) of
    transforms (..., 4, 4)."""
    t = np.asarray(transform, dtype=float)
    return np.concatenate([t[..., :3, 3], spatial.matrix_to_euler_zyx(t[..., :3, :3])], axis=-1)
