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
`joint_harmonics` block), e ~ N(0, s^2 I). The covariance of the stacked residuals is dense in 3n (the a_j differ from row to
row), but the circle kernel is a Fourier series, exp(-(1 - cos d) / l^2) = e^-z I_0(z) + 2 sum_k
e^-z I_k(z) cos(k d), z = 1 / l^2 (I_k the modified Bessel functions): f_j is a sum of the features
a_j(q) cos(k q_j), a_j(q) sin(k q_j) with independent Gaussian weights, cut at the order `harmonics`
beyond which less than `TAIL` of the kernel is left, for every lengthscale within its bounds. The
joint form is then Bayesian linear regression on fixed features (`likelihood.feature_log_evidence`):
its evidence comes from sums over the rows taken once, exact at any number of rows. The free GP's
three axes share one n x n covariance (`likelihood.kron_log_evidence_and_gradient`). Both forms are
compared on every row, each with its hyperparameters at the maximum of its evidence (the model's
parameters integrated with the GP), their difference less half the difference of their
hyperparameter counts times log 3n (each form pays for what it fitted). The free form's n x n
factor per evaluation bounds its search to `MAX_ROWS` rows evenly spaced over the data; above, its
evidence on every row is Titsias' lower bound at the hyperparameters found there
(`with_parameters.titsias_log_evidence`, the residual GP's inducing inputs). Both lower the free
form's evidence, so above `MAX_ROWS` the comparison leans towards the joint-error form by the
bound's gap; benchmarks/bench_gp.py measures it where the exact evidence can still be taken. A joint
is named when taking its f_j out (s_j -> 0, the rest held) costs more than `min_log_evidence_gain`.

A diagnostic: where the residual lives, told in the joints' own terms. Prediction keeps the free GP.
SI inside (m, rad); the report is in degrees where its names say so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .kernels import Hyperparameters, circle_distances, kernel, turned_joints
from .likelihood import feature_log_evidence, kron_log_evidence_and_gradient
from .residual import evenly_spaced, inducing_count
from .with_parameters import titsias_log_evidence

# rows the free form's hyperparameters are maximised on: its n x n factor and inverse per evaluation (a
# few tenths of a second at 1000 on two cores); above, its evidence on every row is Titsias' bound at
# them. The joint form's sums are taken once over every row, its evaluations do not grow with them
MAX_ROWS = 1000
FEATURE_CHUNK = 2000  # rows per block of the joint form's sums (a (3 chunk, P + F) block: ~80 MB at 7 joints)
TAIL = 1e-8  # the share of k(0) the joint form's cut Fourier series may leave out (`harmonics`)
NEGLIGIBLE = 1e-16  # a Fourier weight of the kernel below this is left out of the sums' evaluation
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
    free_method: str = "exact"

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
            "free_form_evidence": self.free_method,
            "rule": "joints in not_seen move the marker by less than 1e-4 of the most moving joint per radian "
            "(the marker on their axis) and have no f_j; each form's hyperparameters at the maximum of its evidence (parameters integrated with the GP), "
            "the joint-error form's on every row, the free form's on at most 1,000 rows (above, its evidence on every row is Titsias' "
            "lower bound at them); joint-error form preferred when its log evidence exceeds the free form's by more than "
            "half the difference of their hyperparameter counts times log 3n; a joint named when its f_j carries "
            "more than the threshold",
        }


def harmonics(shortest: float) -> int:
    """The order K at which the circle kernel's Fourier series (module docstring) may be cut for
    every lengthscale of at least `shortest` (rad): what it leaves out, sum over |k| > K of
    e^-z I_k(z), z = 1 / l^2, is below TAIL of k(0) = 1 (it is largest at the shortest lengthscale)."""
    import scipy.special

    weights = scipy.special.ive(np.arange(0, 4000), 1.0 / shortest**2)
    left = 1.0 - (weights[0] + 2.0 * np.cumsum(weights[1:]))  # left[K - 1]: beyond order K
    return int(np.argmax(left < TAIL)) + 1


def fourier_weights(lengthscale: float, orders: int) -> tuple[np.ndarray, np.ndarray]:
    """(weights (2K + 1,), d log weight / d log lengthscale (2K + 1,)) of the circle kernel's
    features [cos 0q, cos q .. cos Kq, sin q .. sin Kq] at `lengthscale` (rad), K = orders; a weight
    below NEGLIGIBLE is 0 (its derivative too)."""
    import scipy.special

    z = 1.0 / lengthscale**2
    k = np.arange(orders + 2)
    scaled = scipy.special.ive(k, z)  # e^-z I_k(z)
    # d/dz (e^-z I_k) = (e^-z I_{k-1} + e^-z I_{k+1}) / 2 - e^-z I_k, with I_-1 = I_1
    below = np.concatenate([[scaled[1]], scaled[:-2]])
    slope = 0.5 * (below + scaled[1:]) - scaled[:-1]
    weight = np.where(k[:-1] == 0, 1.0, 2.0) * scaled[:-1]
    ratio = np.divide(slope, scaled[:-1], out=np.zeros_like(slope), where=scaled[:-1] > 0) * (-2.0 * z)
    weights = np.concatenate([weight, weight[1:]])
    ratios = np.concatenate([ratio, ratio[1:]])
    small = weights < NEGLIGIBLE
    return np.where(small, 0.0, weights), np.where(small, 0.0, ratios)


def _features(q, directions, turned, orders: int) -> np.ndarray:
    """Phi (3n, F): a_j(q_i) cos(k q_ij) and a_j(q_i) sin(k q_ij) per turned joint j (the joint's
    2K + 1 columns together, in `fourier_weights`' order)."""
    k = np.arange(orders + 1)
    parts = []
    for j in turned:
        angle = q[:, j, None] * k
        trig = np.concatenate([np.cos(angle), np.sin(angle[:, 1:])], axis=1)  # (n, 2K + 1)
        parts.append(directions[:, :, j, None] * trig[:, None, :])  # (n, 3, 2K + 1)
    return np.concatenate(parts, axis=2).reshape(3 * len(q), -1)


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


def _feature_sums(q, y, directions, jacobian, turned, orders: int, chunk: int = FEATURE_CHUNK):
    """(Phi^T Phi, Phi^T y, y^T y) of the joint form's features Phi = [J, features] (3n, P + F) at
    readings q (n, N), y (3n,), jacobian (3n, P), accumulated `chunk` rows at a time."""
    p = jacobian.shape[-1]
    size = p + len(turned) * (2 * orders + 1)
    gram, projected = np.zeros((size, size)), np.zeros(size)
    for begin in range(0, len(q), chunk):
        rows = slice(begin, begin + chunk)
        stacked = slice(3 * begin, 3 * (begin + chunk))
        part = np.concatenate([jacobian[stacked], _features(q[rows], directions[rows], turned, orders)], axis=1)
        gram += part.T @ part
        projected += part.T @ y[stacked]
    return gram, projected, float(y @ y)


def _joint_objective(q, y, directions, jacobian, precision, turned):
    """The joint form's log evidence at x = (log s_j..., log l_j..., log noise) and its gradient,
    with `without` joints' f_j taken out, from the sums of its features taken once."""
    orders = harmonics(LENGTH_BOUNDS[0])
    gram, projected, yy = _feature_sums(q, y, directions, jacobian, turned, orders)
    k, per = len(turned), 2 * orders + 1

    def log_z(x: np.ndarray, without=()) -> tuple[float, np.ndarray]:
        variances, ratios = [], []
        for i in range(k):
            weights, ratio = fourier_weights(math.exp(x[k + i]), orders)
            variances.append(np.zeros(per) if i in without else math.exp(2.0 * x[i]) * weights)
            ratios.append(ratio)
        value, by_variance, by_noise = feature_log_evidence(
            gram, projected, yy, len(y), precision, np.concatenate(variances), math.exp(x[-1])
        )
        by_variance = by_variance.reshape(k, per)
        by_amplitude = 2.0 * by_variance.sum(axis=1)
        by_length = np.sum(by_variance * np.array(ratios), axis=1)
        return value, np.concatenate([by_amplitude, by_length, [by_noise]])

    return log_z


def _free_objective(q, y, jacobian, precision, turned):
    """The free GP's log evidence at x = (log l_j..., log s, log noise) and its gradient, its three
    axes sharing one n x n covariance."""
    cosines = circle_distances(q[:, turned])
    residuals, stacked = y.reshape(-1, 3), jacobian.reshape(len(q), 3, -1)

    def log_z(x: np.ndarray) -> tuple[float, np.ndarray]:
        lengths = np.full(q.shape[1], np.inf)
        lengths[turned] = np.exp(x[: len(turned)])
        hyper = Hyperparameters(lengths, math.exp(x[-2]), math.exp(x[-1]))
        base = kernel(q, q, hyper)
        covariance = base + hyper.noise_std**2 * np.eye(len(q))
        derivatives = [base * 2.0 * c / length**2 for c, length in zip(cosines, lengths[turned])]
        derivatives += [2.0 * base, 2.0 * hyper.noise_std**2 * np.eye(len(q))]
        return kron_log_evidence_and_gradient(residuals, stacked, precision, covariance, derivatives)

    return log_z


def _free_form(q, y, jacobian, precision, turned, free: Hyperparameters) -> tuple[np.ndarray, float, str]:
    """(x, log evidence on every row, how it was computed) of the free form: its hyperparameters x at
    the maximum of its exact evidence on at most MAX_ROWS rows evenly spaced over the data, from
    `free`; above, its evidence on every row is Titsias' bound at them (`with_parameters`)."""
    rows = evenly_spaced(len(q), MAX_ROWS)
    p = jacobian.shape[-1]
    stacked = jacobian.reshape(len(q), 3, p)
    free_lengths = np.clip(free.lengthscales[turned], *LENGTH_BOUNDS)
    start = np.concatenate([np.log(free_lengths), [math.log(free.signal_std), math.log(free.noise_std)]])
    bounds = [(math.log(LENGTH_BOUNDS[0]), math.log(LENGTH_BOUNDS[1]))] * len(turned)
    bounds += [(s - LOG_RANGE, s + LOG_RANGE) for s in start[-2:]]
    objective = _free_objective(q[rows], y[rows].ravel(), stacked[rows].reshape(-1, p), precision, turned)
    x, log_z = _maximise(objective, start, bounds)
    if len(rows) == len(q):
        return x, log_z, "exact"
    lengths = np.full(q.shape[1], np.inf)
    lengths[turned] = np.exp(x[: len(turned)])
    hyper = Hyperparameters(lengths, math.exp(x[-2]), math.exp(x[-1]))
    inducing = inducing_count(q, hyper)
    bound = titsias_log_evidence(q, y, stacked, precision, hyper, inducing)
    return x, bound, f"titsias: hyperparameters from {len(rows)} rows, inducing inputs {inducing}"


def joint_error_form(
    q, residuals, directions, jacobian, precision, free: Hyperparameters, threshold: float
) -> JointErrorForm:
    """Compare the joint-error form with the free GP (module docstring) on the residuals (n, 3) m of
    a fit at readings q (n, N) rad: directions (n, 3, N) m/rad, the marker's motion per radian of
    each joint; jacobian (3n, P) and precision (P,) of the fit's parameters, integrated in both
    (y = residuals + J theta, theta the fit's mode, is passed as residuals already); free: the free
    GP's hyperparameters (its start); threshold (nats) for naming a joint."""
    q, y = np.asarray(q, dtype=float), np.asarray(residuals, dtype=float)
    directions = np.asarray(directions, dtype=float)
    jacobian = np.asarray(jacobian, dtype=float)
    precision = np.asarray(precision, dtype=float)
    flat_y = y.ravel()
    n = len(q)
    turned = np.flatnonzero(turned_joints(q))
    # a joint whose angle error does not move the marker (the marker on its axis) has no f_j the data see
    reach = np.array([math.sqrt(float(np.mean(directions[:, :, j] ** 2))) for j in turned])
    unseen = tuple(f"q{j + 1}" for j in turned[reach <= UNSEEN * reach.max()])
    turned = turned[reach > UNSEEN * reach.max()]
    names = tuple(f"q{j + 1}" for j in turned)
    scale = math.sqrt(float(np.mean(y**2)))

    joint_log_z = _joint_objective(q, flat_y, directions, jacobian, precision, turned)
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

    x_free, log_z_free, free_method = _free_form(q, y, jacobian, precision, turned, free)
    carried = []
    for i in range(len(turned)):
        try:  # f_j taken out, the rest held
            carried.append(log_z_joint - joint_log_z(x_joint, without=(i,))[0])
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
        free_method=free_method,
    )
