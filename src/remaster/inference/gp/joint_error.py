"""What the parametric effects leave, read as joint-angle errors: the residual GP in joint-error form.

The residual GP (`residual`) models what is left as a smooth function of all the joint angles in
the robot frame; a joint-angle error of one joint then shows in every joint whose motion moves the
marker's sensitivity to it (a transmission error of joint 2 is "relevant" to joint 1 too, because
joint 1 turns the direction it moves the marker in). In joint-error form each joint's angle error
is a function of its own angle only, mapped to positions by that joint's column of the
identification Jacobian:

    r_i = sum_j a_j(q_i) f_j(q_ij) + e_i,   f_j ~ GP(0, s_j^2 exp(-(1 - cos(q_j - q_j')) / l_j^2)),

a_j(q) (3,) m/rad the marker's motion per radian of joint j (d predicted / d zero-offset j), the
kernel on the circle of that joint (periodic, every harmonic order at once: the GP form of the
`joint_harmonics` block), e ~ N(0, s^2 I). The covariance of the stacked residuals is dense (3n x
3n: the a_j differ from row to row), so both forms are compared on at most `MAX_ROWS` rows evenly
spaced over the data, each with its hyperparameters at the maximum of its evidence (the model's
parameters integrated with the GP, `likelihood.dense_log_evidence`), their difference less half the
difference of their hyperparameter counts times log 3n (each form pays for what it fitted). A joint
is named when taking its f_j out (s_j -> 0, the rest held) costs more than `min_log_evidence_gain`.

A diagnostic: where the residual lives, told in the joints' own terms. Prediction keeps the free GP.
SI inside (m, rad); the report is in degrees where its names say so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .kernels import Hyperparameters, circle_distances, kernel, turned_joints
from .likelihood import dense_log_evidence_and_gradient
from .residual import evenly_spaced

MAX_ROWS = 250  # rows of the dense comparison (a 750 x 750 factor per evaluation)
LENGTH_BOUNDS = (
    0.05,
    20.0,
)  # rad, a joint's lengthscale on its circle in this form (the free GP: `kernels.LENGTH_BOUNDS`)
UNSEEN = 1e-4  # a joint moving the marker less than this fraction of the most moving one's per radian
LOG_RANGE = 6.0  # the signal's and noise's logs searched this far either side of their starts


@dataclass(frozen=True)
class JointErrorForm:
    """The comparison (JSON-ready through `report`): the maximised log evidences of both forms on
    `rows` rows, the joint form's amplitude (rad) and lengthscale (rad) per turned joint and the
    evidence its f_j carries (nats), and the noise std (m) of each form."""

    rows: int
    log_evidence_joint: float
    log_evidence_free: float
    price: float
    joints: tuple[str, ...]
    amplitudes: np.ndarray
    lengthscales: np.ndarray
    carried: np.ndarray
    noise_joint: float
    noise_free: float
    threshold: float
    unseen: tuple[str, ...] = ()

    @property
    def preferred(self) -> str:
        return "joint_error" if self.log_evidence_joint - self.log_evidence_free - self.price > 0 else "free"

    @property
    def named(self) -> list[str]:
        return [j for j, c in zip(self.joints, self.carried) if c > self.threshold]

    def report(self) -> dict:
        return {
            "rows": self.rows,
            "log_evidence_joint_error_form": self.log_evidence_joint,
            "log_evidence_free_form": self.log_evidence_free,
            "price_nats": self.price,
            "preferred": self.preferred,
            "named_joints": self.named,
            "not_seen": list(self.unseen),
            "threshold_nats": self.threshold,
            "joints": {
                j: {
                    "amplitude_deg": math.degrees(a),
                    "lengthscale_rad": float(l_),
                    "evidence_carried_nats": float(c),
                    "named": bool(c > self.threshold),
                }
                for j, a, l_, c in zip(self.joints, self.amplitudes, self.lengthscales, self.carried)
            },
            "noise_std_mm": {"joint_error_form": self.noise_joint * 1e3, "free_form": self.noise_free * 1e3},
            "rule": "joints in not_seen move the marker by less than 1e-4 of the most moving joint per radian "
            "(the marker on their axis) and have no f_j; each form's hyperparameters at the maximum of its evidence (parameters integrated with the GP) on "
            "the same rows; joint-error form preferred when its log evidence exceeds the free form's by more than "
            "half the difference of their hyperparameter counts times log 3n; a joint named when its f_j carries "
            "more than the threshold",
        }


def _maximise(objective, start: np.ndarray, bounds) -> tuple[np.ndarray, float]:
    """Maximise objective(x) -> (value, gradient) within bounds (L-BFGS-B)."""
    import scipy.optimize

    def negative(x):
        try:
            value, gradient = objective(x)
        except np.linalg.LinAlgError:
            return 1e25, np.zeros_like(x)
        return -value, -gradient

    found = scipy.optimize.minimize(negative, start, jac=True, method="L-BFGS-B", bounds=bounds)
    return found.x, -float(found.fun)


def joint_error_form(
    q, residuals, directions, jacobian, precision, free: Hyperparameters, threshold: float
) -> JointErrorForm:
    """Compare the joint-error form with the free GP (module docstring) on the residuals (n, 3) m of
    a fit at readings q (n, N) rad: directions (n, 3, N) m/rad, the marker's motion per radian of
    each joint; jacobian (3n, P) and precision (P,) of the fit's parameters, integrated in both
    (y = residuals + J theta, theta the fit's mode, is passed as residuals already); free: the free
    GP's hyperparameters (its start); threshold (nats) for naming a joint."""
    q, y = np.asarray(q, dtype=float), np.asarray(residuals, dtype=float)
    rows = evenly_spaced(len(q), MAX_ROWS)
    q, y, directions = q[rows], y[rows], np.asarray(directions, dtype=float)[rows]
    jacobian = (
        np.asarray(jacobian, dtype=float).reshape(-1, 3, jacobian.shape[-1])[rows].reshape(-1, jacobian.shape[-1])
    )
    flat_y = y.ravel()
    n = len(q)
    turned = np.flatnonzero(turned_joints(q))
    # a joint whose angle error does not move the marker (the marker on its axis) has no f_j the data see
    reach = np.array([math.sqrt(float(np.mean(directions[:, :, j] ** 2))) for j in turned])
    unseen = tuple(f"q{j + 1}" for j in turned[reach <= UNSEEN * reach.max()])
    turned = turned[reach > UNSEEN * reach.max()]
    names = tuple(f"q{j + 1}" for j in turned)
    scale = math.sqrt(float(np.mean(y**2)))
    identity = np.eye(3 * n)

    # per turned joint: K_j's exponent and the outer product of its directions, fixed
    cosines = list(circle_distances(q[:, turned]))
    outers = []
    for j in turned:
        v = directions[:, :, j].ravel()
        outers.append(np.outer(v, v))

    def joint_terms(x: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """The joint form's covariance at x = (log s_j, log l_j, log noise) and its derivatives."""
        k = len(turned)
        amplitudes, lengths, noise = np.exp(x[:k]), np.exp(x[k : 2 * k]), math.exp(x[-1])
        covariance = noise**2 * identity
        by_amplitude, by_length = [], []
        for c, o, a, length in zip(cosines, outers, amplitudes, lengths):
            term = a**2 * np.repeat(np.repeat(np.exp(-c / length**2), 3, 0), 3, 1) * o
            covariance += term
            by_amplitude.append(2.0 * term)
            by_length.append(term * np.repeat(np.repeat(2.0 * c / length**2, 3, 0), 3, 1))
        return covariance, by_amplitude + by_length + [2.0 * noise**2 * identity]

    def joint_log_z(x: np.ndarray) -> tuple[float, np.ndarray]:
        covariance, derivatives = joint_terms(x)
        return dense_log_evidence_and_gradient(flat_y, jacobian, precision, covariance, derivatives)

    def free_log_z(x: np.ndarray) -> tuple[float, np.ndarray]:
        lengths = np.full(q.shape[1], np.inf)
        lengths[turned] = np.exp(x[: len(turned)])
        hyper = Hyperparameters(lengths, math.exp(x[-2]), math.exp(x[-1]))
        base = kernel(q, q, hyper)
        covariance = np.kron(base, np.eye(3)) + hyper.noise_std**2 * identity
        derivatives = [np.kron(base * 2.0 * c / length**2, np.eye(3)) for c, length in zip(cosines, lengths[turned])]
        derivatives += [2.0 * np.kron(base, np.eye(3)), 2.0 * hyper.noise_std**2 * identity]
        return dense_log_evidence_and_gradient(flat_y, jacobian, precision, covariance, derivatives)

    norms = np.array([math.sqrt(float(np.mean(directions[:, :, j] ** 2))) for j in turned])
    start_joint = np.concatenate(
        [
            np.log(scale / np.maximum(norms, 1e-9) / math.sqrt(len(turned))),
            np.zeros(len(turned)),
            [math.log(free.noise_std)],
        ]
    )
    log_bounds = [(math.log(LENGTH_BOUNDS[0]), math.log(LENGTH_BOUNDS[1]))]
    bounds_joint = (
        [(s - LOG_RANGE, s + LOG_RANGE) for s in start_joint[: len(turned)]]
        + log_bounds * len(turned)
        + [(start_joint[-1] - LOG_RANGE, start_joint[-1] + LOG_RANGE)]
    )
    x_joint, log_z_joint = _maximise(joint_log_z, start_joint, bounds_joint)

    free_lengths = np.clip(free.lengthscales[turned], *LENGTH_BOUNDS)
    start_free = np.concatenate([np.log(free_lengths), [math.log(free.signal_std), math.log(free.noise_std)]])
    bounds_free = log_bounds * len(turned) + [(s - LOG_RANGE, s + LOG_RANGE) for s in start_free[-2:]]
    x_free, log_z_free = _maximise(free_log_z, start_free, bounds_free)

    carried = []
    for i in range(len(turned)):
        without = x_joint.copy()
        without[i] = math.log(1e-12)  # f_j taken out, the rest held
        try:
            carried.append(log_z_joint - joint_log_z(without)[0])
        except np.linalg.LinAlgError:  # without it the rest cannot hold the data at all
            carried.append(math.inf)
    price = 0.5 * ((2 * len(turned) + 1) - (len(turned) + 2)) * math.log(3 * n)
    k = len(turned)
    return JointErrorForm(
        rows=n,
        log_evidence_joint=float(log_z_joint),
        log_evidence_free=float(log_z_free),
        price=float(price),
        joints=names,
        amplitudes=np.exp(x_joint[:k]),
        lengthscales=np.exp(x_joint[k : 2 * k]),
        carried=np.array(carried),
        noise_joint=math.exp(x_joint[-1]),
        noise_free=math.exp(x_free[-1]),
        threshold=float(threshold),
        unseen=unseen,
    )
