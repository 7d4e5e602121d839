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

Where the residual GP read in joint-error form is preferred by the evidence
(`inference.gp.joint_error`: each turned joint's angle error f_j(q_j), a GP on that joint's circle,
moving the marker along a_j(q), the marker's motion per radian of joint j), the field is taken in
that form: e(q) = sum_j a_j(q) f_j(q_j), its covariance the circle kernel's Fourier series, each
f_j's constant left out. A joint's error averaged over its whole turn is its zero-offset, as the
joint_harmonics block (orders 1 and up) and a transmission error's definition have it: what the
fit cannot tell from the zero-offset is the part of f_j's harmonics the design's angles do not
average out, which is the share u_model gives. The form's amplitudes and lengthscales are fitted
with the model's parameters integrated, so the part of the field a zero-offset absorbs is priced in
them; the free kernel is fitted on what the model could not absorb, and a field whose absorbed part
is larger than its visible part (smooth over the design, short in the residual) is understated in
it. Where a joint's lengthscale in that form ends on its lower bound, f_j takes up structure shorter
than any joint error the form allows, not that joint's error: the free form is taken. A joint never
turned has no f_j: its error at the one angle it was held at is its zero-offset
to the fit, and no field of the data says how much of it. Measured on simulated loops that did not
close in docs/validation.md.

SI inside (rad); the report is JSON-ready in degrees where its keys say so.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..inference.gp.joint_error import LENGTH_BOUNDS, fourier_weights, harmonics
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
BOUND_TOLERANCE = 1e-3  # a log lengthscale this close to the joint-error form's bound is on it (`kernels.at_bounds`)
JOINT_METHOD = (
    "the residual field's share in joint-error form, which the evidence prefers: each turned joint's angle error a GP "
    "on its circle (the form's amplitude and lengthscale, fitted with the model's parameters integrated), its constant "
    "left out (a joint's error averaged over its turn is its zero-offset), propagated through the fit, "
    "u_model^2 = diag(B K B^T), K = sum_j A_j K_j A_j^T, B = C J^T W / sigma^2"
)


@dataclasses.dataclass(frozen=True)
class JointField:
    """A residual field in joint-error form (`inference.gp.joint_error`): the angle error of each joint
    in `joints` (indices), a GP on its circle of `amplitudes` and `lengthscales` (rad), moving the marker
    by directions[:, :, j] (n, 3, N) m/rad at the fit's readings (`joint_form.joint_directions`)."""

    joints: np.ndarray
    amplitudes: np.ndarray
    lengthscales: np.ndarray
    directions: np.ndarray

    @staticmethod
    def at_lower_bound(report: dict | None) -> list[str]:
        """The joints of a `JointErrorForm.report()` whose lengthscale ended on the form's lower bound
        (`joint_error.LENGTH_BOUNDS`): there f_j is as short as the form allows and takes up what is not
        its joint's own error (docs/validation.md, the residual GP in joint-error form), so its
        amplitude is not a joint error's size."""
        shortest = math.log(LENGTH_BOUNDS[0]) + BOUND_TOLERANCE
        joints = (report or {}).get("joints") or {}
        return [name for name, j in joints.items() if math.log(j["lengthscale_rad"]) < shortest]

    @classmethod
    def taken(cls, report: dict | None) -> bool:
        """Whether a `JointErrorForm.report()` gives the field: the evidence prefers the joint-error form
        and no joint's lengthscale is on its lower bound (`at_lower_bound`)."""
        return bool(
            report
            and report.get("preferred") == "joint_error"
            and report.get("joints")
            and not cls.at_lower_bound(report)
        )

    @classmethod
    def preferred(cls, report: dict | None, directions: np.ndarray) -> JointField | None:
        """The field of a `JointErrorForm.report()` where it is `taken`, else None."""
        if not cls.taken(report):
            return None
        joints = report["joints"]
        return cls(
            np.array([int(name[1:]) - 1 for name in joints]),
            np.radians([j["amplitude_deg"] for j in joints.values()]),
            np.array([j["lengthscale_rad"] for j in joints.values()], dtype=float),
            np.asarray(directions, dtype=float),
        )

    def report(self) -> dict:
        return {
            f"q{j + 1}": {"amplitude_deg": float(np.degrees(a)), "lengthscale_rad": float(length)}
            for j, a, length in zip(self.joints, self.amplitudes, self.lengthscales)
        }


def joint_field_variance(q, field: JointField, sensitivity_rows: np.ndarray) -> np.ndarray:
    """(m,) the variance of each of m linear functionals of a joint-error field (`JointField`):
    sensitivity_rows (m, n, 3) applied to e(q_i) = sum_j a_j(q_i) f_j(q_ij) at readings q (n, N) rad,
    f_j a GP on joint j's circle without its constant (module docstring), through the circle
    kernel's Fourier series cut where less than `joint_error.TAIL` of it is left."""
    q = np.asarray(q, dtype=float)
    b = np.asarray(sensitivity_rows, dtype=float)
    total = np.zeros(b.shape[0])
    for j, amplitude, lengthscale in zip(field.joints, field.amplitudes, field.lengthscales):
        orders = harmonics(lengthscale)
        weights, _ = fourier_weights(lengthscale, orders)  # [cos 0q .. cos Kq, sin q .. sin Kq]
        weights[0] = 0.0  # the constant: the zero-offset itself, not an error of it
        angle = q[:, j, None] * np.arange(orders + 1)
        features = np.concatenate([np.cos(angle), np.sin(angle[:, 1:])], axis=1)  # (n, 2K + 1)
        through = np.einsum("mni,ni,nf->mf", b, field.directions[:, :, j], features)
        total += amplitude**2 * (through**2 @ weights)
    return total


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


def zero_offset_model_error(
    fitted: Fitted,
    hyper: Hyperparameters | None,
    closed: bool | None,
    gp_added: bool,
    joint_field: JointField | None = None,
) -> dict:
    """The residual field's share of the fit's free zero-offsets (module docstring). hyper: the
    residual GP's kernel when the loop fitted one (None: fitted here on the fit's residuals; the three
    axes alike, the frame does not matter); closed: the closure test's verdict;
    gp_added: the residual GP is part of the calibration; joint_field: the residual GP in joint-error
    form where the evidence prefers it (`JointField.preferred`), the field then taken in that form.
    JSON-ready: computed, why or method, the form, the kernel (the free form's, which the declared
    model error's draws use), the joint field where taken, and per zero-offset u_model_deg."""
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
    through = sensitivity(fitted, rows)
    if joint_field is not None:
        variance, form = (
            joint_field_variance(q, joint_field, through),
            {
                "method": JOINT_METHOD,
                "form": "joint_error",
                "joint_field": joint_field.report(),
            },
        )
    else:
        # the signal's variance is the field's; the kernel's noise is the posterior's own share
        variance = field_variance(q, dataclasses.replace(hyper, noise_std=0.0), through)
        form = {"method": METHOD, "form": "free"}
    u_model = np.sqrt(np.maximum(variance, 0.0))
    return {
        "computed": True,
        **form,
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
