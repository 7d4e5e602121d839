"""The zero-offsets' share of what the parametric model lacks: how far a smooth residual field over
the joints moves the loop model's zero-offsets, a component of the certificate's U wherever such a
field is part of the calibration (the residual GP added) or declared (the loop not closed).

The posterior treats the residual as independent noise. A field e(q) the model lacks is correlated
over the configurations, and the part of it that looks like a zero-offset is absorbed by the fit:
it is in neither the residual nor the posterior std, and a jackknife over groups of poses does not
see it either (every group carries the same field). To first order the mode moves by

    delta theta = C J^T W e / sigma^2,

C the Laplace covariance of theta, J (3n, P) the whitened predictions' Jacobian, W the noise's
whitening (`remaster.noise`; the identity for isotropic noise) and sigma the noise std. With e a
Gaussian process over the joints, independent and alike on the three axes (Kennedy & O'Hagan 2001:
the model discrepancy), of kernel k fitted on what the model left (the residual GP's kernel,
`inference.gp.kernels.kernel`: periodic in each turned joint, so q and q + 2 pi are one
configuration), the zero-offsets' added variance is

    u_model^2 = diag(sum_a B_a K B_a^T),   B = C J^T W / sigma^2,

B_a its columns on axis a (P, n) and K = k(q_i, q_k) over the optimization set's n configurations.
The mode keeps its value; only the uncertainty widens, as a Type B component (nu = inf).

Limits: the kernel is fitted to the part of the field the model could not absorb; a field whose
absorbed part is larger than its visible part (smooth over the design, short in the residual) is
understated. Measured on simulated loops that did not close in docs/validation.md.

SI inside (rad); the report is JSON-ready in degrees where its keys say so.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..inference.gp.kernels import Hyperparameters, kernel, turned_joints
from ..inference.gp.residual import fit_hyperparameters
from ..units import DEG
from .fitted import Fitted
from .jackknife import ZERO_OFFSET_PREFIX

ROW_CHUNK = 1024  # rows of the kernel held at once: (chunk, n) floats
# the kernel's hyperparameters are fitted on the rows themselves (no cross-validation by pose, unlike
# the GP candidate): a few distinct configurations per hyperparameter, as for any regression
ROWS_PER_HYPERPARAMETER = 5
METHOD = (
    "the residual field's share: a Gaussian process over the joints (the residual GP's kernel, fitted on what the "
    "model left) propagated through the fit, u_model^2 = diag(B K B^T), B = C J^T W / sigma^2"
)


def applies(closed: bool | None, gp_added: bool) -> bool:
    """Whether the calibration carries a residual field: the residual GP added, or the loop not closed."""
    return gp_added or closed is False


def sensitivity(fitted: Fitted, rows: np.ndarray) -> np.ndarray:
    """(len(rows), n, 3) rad/m: how the free parameters `rows` (indices) of the fit's mode move with a
    residual e (n, 3) m added to its measured positions, B = C J^T W / sigma^2 (module docstring)."""
    mode = fitted.mode
    p, n = len(mode.theta), fitted.model.n_points
    jacobian = mode.jacobian[: 3 * n]  # the positions' rows; a full-pose probe's orientations follow
    out = (mode.covariance[rows][:, :p] @ jacobian.T / mode.sigma**2).reshape(len(rows), n, 3)
    return np.einsum("pni,nij->pnj", out, fitted.model.whitening_matrices())


def field_variance(q, hyper: Hyperparameters, sensitivity_rows: np.ndarray, chunk: int = ROW_CHUNK) -> np.ndarray:
    """(m,) the variance of each of m linear functionals of a residual field: sensitivity_rows
    (m, n, 3) applied to a Gaussian process over readings q (n, N) rad of kernel `hyper`, independent
    and alike on the three axes: diag(sum_a B_a K B_a^T), K built `chunk` rows at a time."""
    q = np.asarray(q, dtype=float)
    b = np.asarray(sensitivity_rows, dtype=float)
    total = np.zeros(b.shape[0])
    for start in range(0, len(q), chunk):
        block = kernel(q[start : start + chunk], q, hyper)  # (c, n)
        for axis in range(3):
            total += np.einsum("mc,mc->m", b[:, start : start + chunk, axis], b[:, :, axis] @ block.T)
    return total


def zero_offset_model_error(fitted: Fitted, hyper: Hyperparameters | None, closed: bool | None, gp_added: bool) -> dict:
    """The residual field's share of the fit's free zero-offsets (module docstring). hyper: the
    residual GP's kernel when the loop fitted one (None: fitted here on the fit's residuals; the three
    axes alike, the frame does not matter); closed: the closure test's verdict;
    gp_added: the residual GP is part of the calibration. JSON-ready: computed, why or method, the
    kernel, and per zero-offset u_model_deg."""
    if not applies(closed, gp_added):
        return {"computed": False, "why": "the loop closed without a residual field: its residual is the noise"}
    names = fitted.model.names
    rows = np.array([i for i, name in enumerate(names) if name.startswith(ZERO_OFFSET_PREFIX)], dtype=int)
    if len(rows) == 0:
        return {"computed": False, "why": "no zero-offset is free in the loop model"}
    q = fitted.model.data.q
    hyperparameters = int(turned_joints(q).sum()) + 2  # a lengthscale per turned joint, signal and noise
    configurations = len(np.unique(np.round(q, 6), axis=0))
    if hyper is None and configurations < ROWS_PER_HYPERPARAMETER * hyperparameters:
        return {
            "computed": False,
            "why": f"{configurations} configurations: fewer than {ROWS_PER_HYPERPARAMETER} per hyperparameter of the "
            f"field's kernel ({hyperparameters}) leave it undetermined",
        }
    if hyper is None:
        hyper = fit_hyperparameters(q, fitted.residuals())
    # the signal's variance is the field's; the kernel's noise is the posterior's own share
    field = dataclasses.replace(hyper, noise_std=0.0)
    u_model = np.sqrt(np.maximum(field_variance(q, field, sensitivity(fitted, rows)), 0.0))
    return {
        "computed": True,
        "method": METHOD,
        "kernel": hyper.report(),
        "parameters": {names[i]: {"u_model_deg": float(u / DEG)} for i, u in zip(rows, u_model)},
    }


def not_computed_warning(share: dict, closed: bool | None, gp_added: bool) -> list[str]:
    """The loop report's warning when the calibration carries a residual field whose share of the
    zero-offsets could not be computed (`zero_offset_model_error`'s why), else none."""
    if share.get("computed") or not applies(closed, gp_added):
        return []
    return [
        "the loop-closed model's residual holds a field it lacks, and its share of the zero-offsets is not "
        f"computed ({share['why']}): their U holds the posterior and the between-design spread only, and "
        "understates what that field moves them by"
    ]
