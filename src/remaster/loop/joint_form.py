"""The loop closure's residual GP read in joint-error form (`remaster.inference.gp.joint_error`): the
directions each joint's angle error moves the marker in, at the optimization readings, and the
comparison of the two forms on what the final parametric fit leaves.

SI inside (m, rad).
"""

from __future__ import annotations

import numpy as np

from ..inference import blocks
from ..inference.gp import joint_error
from ..inference.identifiability import JACOBIAN_STEP
from ..inference.readings import Readings
from ..robot.kinematics import KinematicChain
from .selection import Selection


def joint_directions(chain: KinematicChain, data: Readings, marker, t_nr, values: dict) -> np.ndarray:
    """(n, 3, N) m/rad: d predicted (sensor frame) / d zero-offset of each joint at the readings,
    the paper's model at `values` ({name: value}; its registration and zero-offsets are taken)."""
    probe = blocks.BlockModel(chain, data, marker, t_nr, (), {})
    theta = probe.vector({k: v for k, v in values.items() if k in probe.names})
    jacobian = -probe.jacobian(theta, JACOBIAN_STEP).reshape(len(data.q), 3, -1)
    columns = [probe.names.index(f"zero_offsets.q{j + 1}") for j in range(chain.n_joints)]
    return jacobian[:, :, columns]


def joint_error_form(
    selection: Selection, chain: KinematicChain, data: Readings, marker, t_nr, threshold: float
) -> dict | None:
    """JSON-ready `joint_error.JointErrorForm` report of what the final parametric fit leaves on the
    optimization readings, the free GP's hyperparameters as the free form's start; None when the GP
    was not tried."""
    if selection.gp is None:
        return None
    mode = selection.final.mode
    pseudo = mode.model.whitened(mode.residuals) + (mode.jacobian @ mode.theta).reshape(-1, 3)
    directions = mode.model.whitened(
        np.moveaxis(joint_directions(chain, data, marker, t_nr, selection.final.values()), 2, 0)
    )
    try:
        found = joint_error.joint_error_form(
            data.q,
            pseudo,
            np.moveaxis(directions, 0, 2),
            mode.jacobian,
            mode.model._prior_precision,
            selection.gp.gp.hyper,
            threshold,
        )
    except (np.linalg.LinAlgError, ValueError) as exc:  # a diagnostic that cannot be computed is said, not raised
        return {"computed": False, "why": f"the joint-error form could not be computed: {exc}"}
    return found.report()
