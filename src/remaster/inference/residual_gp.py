"""What no parametric effect explains: a Gaussian process over the joint angles.

After the parametric effects, the residual r(q) (3,) m at joint readings q (N,) rad is modelled as

    r(q) = g(q) + e,   g_x, g_y, g_z ~ GP(0, k) independent with one kernel,   e ~ N(0, noise^2 I3),
    k(q, q') = s^2 exp(-sum_j (1 - cos(q_j - q'_j)) / l_j^2),

the squared exponential on the circle of each joint (1 - cos d = 2 sin^2(d / 2): periodic in 2 pi,
so one turn apart is the same angle; over a small range it is the plain squared exponential of
length l_j). A joint the data never turn has no lengthscale. The residual is expressed in the
ROBOT frame (rotated back by the fit's registration), so the correction travels with the robot.

Hyperparameters (l_j, s, noise) maximise the exact marginal likelihood of at most `subset` rows
evenly spaced over the data (analytic gradient, L-BFGS-B in logs, two starts): O(subset^3)
whatever n. Prediction uses all n rows through m inducing inputs (the same kind of
subset), the DTC / projected-process approximation (Seeger, Williams & Lawrence 2003;
Quinonero-Candela & Rasmussen 2005): O(n m^2) time and O(chunk m) memory. Far from every inducing
input the mean returns to zero and the variance to s^2: the correction does not extrapolate, it
says it does not know. The evidence the loop decides with is not the DTC
likelihood (which can be far above or below the exact one): `remaster.inference.gp_evidence`.

Relevance of joint j: its measured range (max - min of q_j) over l_j, the number of lengthscales
the data cross along it; the residual "depends on" the joints where it is at least
`RELEVANT_RANGE`.

SI inside (m, rad).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)
import pandas as pd

SUBSET = 600  # rows for the hyperparameters (exact marginal likelihood)
INDUCING = 400  # inducing inputs for prediction (and the evidence's bound above EXACT_ROWS)
EXACT_ROWS = 3000  # rows up to which the evidence is the exact marginal likelihood (`gp_evidence`)
CHUNK = 8192  # rows per block when accumulating over all n
STILL = 1e-6  # rad: a joint whose range is below this is not turned by the data
RELEVANT_RANGE = 0.5  # lengthscales crossed over the measured range: the residual depends on that joint
LENGTH_BOUNDS = (0.02, 50.0)  # rad
JITTER = 1e-8  # relative to s^2, for the inducing covariance's Cholesky factor
LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class Hyperparameters:
    """lengthscales (N,) rad, inf for a joint the data never turn; signal_std s and noise_std (m,
    per axis)."""

    lengthscales: np.ndarray
    signal_std: float
    noise_std: float

    @property
    def turned(self) -> np.ndarray:
        return np.isfinite(self.lengthscales)

    def report(self) -> dict:
        return {
            "lengthscales_rad": [None if not np.isfinite(v) else float(v) for v in self.lengthscales],
            "signal_std_m": self.signal_std,
            "noise_std_m": self.noise_std,
        }

    @classmethod
    def from_report(cls, report: dict) -> Hyperparameters:
        return cls(
            np.array([np.inf if v is None else float(v) for v in report["lengthscales_rad"]]),
            float(report["signal_std_m"]),
            float(report["noise_std_m"]),
        )


def kernel(qa, qb, hyper: Hyperparameters) -> np.ndarray:
    """k(qa_i, qb_k) (na, nb) for readings qa (na, N) and qb (nb, N) rad."""
    turned = hyper.turned
    a, b = np.asarray(qa, dtype=float)[:, turned], np.asarray(qb, dtype=float)[:, turned]
    weight = 1.0 / hyper.lengthscales[turned] ** 2
    # sum_j w_j (1 - cos(a_j - b_j)) = sum w - (cos a w) . cos b - (sin a w) . sin b: two products
    exponent = weight.sum() - (np.cos(a) * weight) @ np.cos(b).T - (np.sin(a) * weight) @ np.sin(b).T
    return hyper.signal_std**2 * np.exp(-np.maximum(exponent, 0.0))


def evenly_spaced(n: int, count: int) -> np.ndarray:
    """At most `count` row indices spread evenly over n rows (all of them when n <= count):
    deterministic, and representative when rows are in measurement order."""
    return np.arange(n) if n <= count else np.unique(np.linspace(0, n - 1, count).round().astype(int))


def _negative_log_ml(log_params: np.ndarray, distances: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """-log p(y) of the exact GP and its gradient in (log l_j..., log s, log noise); distances
    (J, n, n) the per-joint 1 - cos differences, y (n, 3)."""
    import scipy.linalg

    n_len = len(distances)
    weights = np.exp(-2.0 * log_params[:n_len])
    signal2, noise2 = math.exp(2.0 * log_params[n_len]), math.exp(2.0 * log_params[n_len + 1])
    shape = np.exp(-np.tensordot(weights, distances, axes=1))
    cov = signal2 * shape
    cov[np.diag_indices_from(cov)] += noise2
    try:
        factor = scipy.linalg.cho_factor(cov, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return 1e25, np.zeros_like(log_params)
    alpha = scipy.linalg.cho_solve(factor, y, check_finite=False)
    n, outputs = y.shape
    log_det = 2.0 * np.sum(np.log(np.diag(factor[0])))
    value = 0.5 * float(np.sum(y * alpha)) + 0.5 * outputs * log_det + 0.5 * n * outputs * LOG_2PI
    inverse = scipy.linalg.cho_solve(factor, np.eye(n), check_finite=False)
    w = alpha @ alpha.T - outputs * inverse  # d log p = 1/2 tr(W dK)
    g = w * (signal2 * shape)
    gradient = np.empty_like(log_params)
    gradient[:n_len] = weights * np.tensordot(distances, g, axes=((1, 2), (0, 1)))  # 1/2 * 2 w_j sum(D_j G)
    gradient[n_len] = float(np.sum(g))
    gradient[n_len + 1] = noise2 * float(np.trace(w))
    return value, -gradient


def fit_hyperparameters(q, residuals, subset: int = SUBSET, start: Hyperparameters | None = None) -> Hyperparameters:
    """Type-II maximum likelihood of (l_j, s, noise) on at most `subset` evenly spaced rows of q
    (n, N) rad and residuals (n, 3) m; from `start` when given (one start), else from a smooth
    and a wiggly start."""
    import scipy.optimize

    q, y = np.asarray(q, dtype=float), np.asarray(residuals, dtype=float)
    rows = evenly_spaced(len(q), subset)
    q_s, y_s = q[rows], y[rows]
    spread = np.ptp(q, axis=0)
    turned = spread > STILL
    unit = float(np.sqrt(np.mean(y_s**2))) or 1.0  # work in units of the residual's size
    y_s = y_s / unit
    distances = 1.0 - np.cos(q_s[:, None, turned] - q_s[None, :, turned])  # (n, n, J)
    distances = np.ascontiguousarray(np.moveaxis(distances, -1, 0))
    span = np.clip(spread[turned], LENGTH_BOUNDS[0], LENGTH_BOUNDS[1])
    bounds = [tuple(np.log(LENGTH_BOUNDS))] * int(turned.sum()) + [
        (math.log(1e-4), math.log(10.0)),
        (math.log(1e-3), math.log(10.0)),
    ]
    if start is None:  # a smooth and a wiggly start: the likelihood can have both modes
        starts = [
            np.concatenate([np.log(np.maximum(f * span, LENGTH_BOUNDS[0])), [math.log(0.7)] * 2]) for f in (1.0, 0.25)
        ]
    else:
        lengths = np.clip(
            np.where(np.isfinite(start.lengthscales), start.lengthscales, span.max() if span.size else 1.0),
            *LENGTH_BOUNDS,
        )[turned]
        starts = [
            np.concatenate(
                [np.log(lengths), np.log(np.clip([start.signal_std / unit, start.noise_std / unit], 1e-3, 10.0))]
            )
        ]
    best = None
    for x0 in starts:
        result = scipy.optimize.minimize(
            _negative_log_ml, x0, args=(distances, y_s), jac=True, method="L-BFGS-B", bounds=bounds
        )
        if best is None or result.fun < best.fun:
            best = result
    lengths = np.full(q.shape[1], np.inf)
    lengths[turned] = np.exp(best.x[: int(turned.sum())])
    return Hyperparameters(lengths, unit * math.exp(best.x[-2]), unit * math.exp(best.x[-1]))


class ResidualGP:
    """The GP conditioned on residuals (n, 3) m at readings q (n, N) rad with given hyperparameters,
    through `inducing` inducing inputs (DTC). `mean`, `variance` at any readings; `log_likelihood`
    of the training residuals."""

    def __init__(self, q, residuals, hyper: Hyperparameters, inducing: int = INDUCING):
        import scipy.linalg

        q, y = np.asarray(q, dtype=float), np.asarray(residuals, dtype=float)
        self.hyper = hyper
        self.inducing = q[evenly_spaced(len(q), inducing)]
        m, noise2 = len(self.inducing), hyper.noise_std**2
        k_mm = kernel(self.inducing, self.inducing, hyper)
        k_mm[np.diag_indices(m)] += JITTER * hyper.signal_std**2
        gram, projected = np.zeros((m, m)), np.zeros((m, y.shape[1]))
        for begin in range(0, len(q), CHUNK):
            k_mn = kernel(self.inducing, q[begin : begin + CHUNK], hyper)
            gram += k_mn @ k_mn.T
            projected += k_mn @ y[begin : begin + CHUNK]
        a = noise2 * k_mm + gram
        a[np.diag_indices(m)] += JITTER * hyper.signal_std**2 * noise2
        self._k_factor = scipy.linalg.cho_factor(k_mm, lower=True)
        self._a_factor = scipy.linalg.cho_factor(a, lower=True)
        self.weights = scipy.linalg.cho_solve(self._a_factor, projected)  # (m, 3): mean = K*m weights
        n, outputs = y.shape
        log_det = (
            2.0 * np.sum(np.log(np.diag(self._a_factor[0])))
            - 2.0 * np.sum(np.log(np.diag(self._k_factor[0])))
            + (n - m) * math.log(noise2)
        )
        quadratic = (float(np.sum(y * y)) - float(np.sum(projected * self.weights))) / noise2
        self.log_likelihood = -0.5 * (quadratic + outputs * log_det + n * outputs * LOG_2PI)
        self.n_rows = n

    def mean(self, q) -> np.ndarray:
        """Posterior mean of g (n*, 3) m at readings q (n*, N) rad."""
        return kernel(np.asarray(q, dtype=float), self.inducing, self.hyper) @ self.weights

    def variance(self, q) -> np.ndarray:
        """Posterior variance of each component of g (n*,) m^2 at readings q (n*, N), without the
        noise: s^2 far from the data."""
        import scipy.linalg

        k_sm = kernel(np.asarray(q, dtype=float), self.inducing, self.hyper)
        explained = np.sum(k_sm.T * scipy.linalg.cho_solve(self._k_factor, k_sm.T), axis=0)
        left = self.hyper.noise_std**2 * np.sum(k_sm.T * scipy.linalg.cho_solve(self._a_factor, k_sm.T), axis=0)
        return np.maximum(self.hyper.signal_std**2 - explained + left, 0.0)


def relevance(hyper: Hyperparameters, q) -> np.ndarray:
    """(N,) measured range of each joint over its lengthscale (0 for a joint never turned)."""
    spread = np.ptp(np.asarray(q, dtype=float), axis=0)
    return np.where(hyper.turned, spread / np.where(hyper.turned, hyper.lengthscales, 1.0), 0.0)


def iid_log_likelihood(residuals) -> float:
    """log p of residuals (n, 3) m under N(0, sigma^2) per component at sigma's maximum likelihood."""
    r = np.asarray(residuals, dtype=float)
    k = r.size
    return -0.5 * k * (LOG_2PI + math.log(float(np.sum(r * r)) / k) + 1.0)


@dataclass(frozen=True, eq=False)
class Candidate:
    """The GP as a candidate of the loop: fitted on every row, its evidence gain over independent
    noise (nats; `evidence` says how it was obtained), and its pose-grouped cross-validation: mse (K,) m^2 per point of the held-out
    residuals less the GP's prediction from the other folds, points (K,)."""

    gp: ResidualGP
    q: np.ndarray
    residuals: np.ndarray
    log_evidence_gain: float
    mse: np.ndarray
    points: np.ndarray
    evidence: object = None  # gp_evidence.GPEvidence: how the gain was obtained

    def relevance(self) -> np.ndarray:
        return relevance(self.gp.hyper, self.q)


def candidate(
    q, residuals, held_out, folds, subset: int = SUBSET, inducing: int = INDUCING, exact_rows: int = EXACT_ROWS
) -> Candidate:
    """Fit and score the GP on readings q (n, N) rad and residuals (n, 3) m of the current model;
    held_out (n, 3) m: each row's residual under the current model fitted without its fold, folds
    (n,) the pose-grouped folds.

    Evidence (`remaster.inference.gp_evidence`): the GP's marginal likelihood, exact up to
    exact_rows rows and Titsias' bound above, with its hyperparameters integrated by a Laplace step
    in their logs, against independent noise with sigma integrated the same way; the parametric
    parameters stay at the current mode in both. Cross-validation: for each fold the GP's
    hyperparameters are refitted on the other folds (from the whole set's, which saves most of the
    cost) and it is conditioned on their residuals; its mean is subtracted from the fold's held-out
    residuals. Hyperparameters fitted with the held-out rows would tune their lengthscales to the
    very noise they then predict (a few per cent of spurious gain on pure noise)."""
    q, residuals, held_out = (np.asarray(a, dtype=float) for a in (q, residuals, held_out))
    hyper = fit_hyperparameters(q, residuals, subset)
    gp = ResidualGP(q, residuals, hyper, inducing)
    from . import gp_evidence  # it builds on this module's kernel

    price = 0.5 * (int(hyper.turned.sum()) + 1) * math.log(residuals.size)
    dtc_gain = gp.log_likelihood - iid_log_likelihood(residuals) - price  # the former measure, for comparison
    scored = gp_evidence.log_evidence_gain(q, residuals, hyper, exact_rows, inducing, subset)
    scored = dataclasses.replace(scored, dtc_gain=float(dtc_gain))
    mse, points = [], []
    for fold in np.unique(folds):
        train = folds != fold
        fold_hyper = fit_hyperparameters(q[train], residuals[train], subset, start=hyper)
        corrected = held_out[~train] - ResidualGP(q[train], residuals[train], fold_hyper, inducing).mean(q[~train])
        mse.append(float(np.mean(np.sum(corrected**2, axis=1))))
        points.append(int((~train).sum()))
    return Candidate(gp, q, residuals, scored.gain, np.array(mse), np.array(points), scored)


def training_frame(candidate: Candidate) -> pd.DataFrame:
    """The GP's training rows: readings q1..qN (rad) and robot-frame residuals rx, ry, rz (m)."""
    q = pd.DataFrame(candidate.q, columns=[f"q{j + 1}" for j in range(candidate.q.shape[1])])
    return q.assign(rx=candidate.residuals[:, 0], ry=candidate.residuals[:, 1], rz=candidate.residuals[:, 2])


def from_results(frame: pd.DataFrame, section: dict | None) -> ResidualGP | None:
    """The loop's GP from its training rows (`training_frame`) and the `residual_gp` section of
    loop_closure.json (hyperparameters, inducing count); None when it was not added."""
    if not section or not section.get("added") or frame is None or frame.empty:
        return None
    q = frame[[c for c in frame.columns if c.startswith("q")]].to_numpy(float)
    return ResidualGP(
        q,
        frame[["rx", "ry", "rz"]].to_numpy(float),
        Hyperparameters.from_report(section["hyperparameters"]),
        int(section["inducing"]),
    )
