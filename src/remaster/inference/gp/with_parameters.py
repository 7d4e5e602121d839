"""A parametric model with the residual Gaussian process present: its evidence and cross-validation
with the parameters integrated together with the GP, not fitted first and the GP put on what they leave.

Fitting the parameters first under independent noise lets a parameter absorb part of a joint-space
error it only resembles (a sensor scale standing in for a transmission error), and the GP then
explains what is left either way: comparing two models by "their Laplace evidence plus the GP's gain
on their residuals" keeps the proxy. Here the model is linearised at its mode theta* (J, 3n x P,
d predicted / d theta), y = r(theta*) + J theta* its pseudo-data (n, 3), and

    y = J theta + g + e,   g_a ~ GP(0, k) per axis a (`kernels.kernel`),   e ~ N(0, s^2 I),
    theta_k ~ N(0, tau_k^2) for the extension blocks, flat for the base blocks,

so that theta is integrated in closed form. With K the n x n kernel matrix and C0 = K + s^2 I, the
noise and GP covariance of the stacked y is C0 (x) I3 (the kernel is the same on the three axes and
invariant under the registration's rotation), and with A = sum_a J_a^T C0^-1 J_a + diag(1 / tau^2)
(0 for the flat blocks), b = sum_a J_a^T C0^-1 y_a:

    log Z = -1/2 sum_a y_a^T C0^-1 y_a + 1/2 b^T A^-1 b - 3/2 log|C0| - 1/2 log|A|
            - 3n/2 log 2 pi + 1/2 sum_k log(1 / tau_k^2) + (F / 2) log 2 pi,

F the flat parameters: their improper constant is common to every model of the same base blocks,
as in the Laplace evidence (`remaster.inference.evidence`), so log Z of two models that differ by an
extension block compare like with like. The GP's hyperparameters are each model's own (fitted to
its residuals, `residual.fit_hyperparameters`) and held: the comparison is conditional on them.

Cross-validation by the same pose folds: for each held-out fold H, theta is estimated from the
other rows T by generalised least squares under C0_TT and the priors, and the fold is predicted by
J_H theta_T + K_HT C0_TT^-1 (y_T - J_T theta_T) (the best linear unbiased predictor of a model with
a GP: kriging with the parametric trend); the error is the held-out mean squared residual per point.

One n x n Cholesky factor per model and per fold: exact up to `MAX_ROWS` rows. Above, the same
model through m inducing inputs (`residual.inducing_count`, evenly spaced as the residual GP's own): K is
replaced by Q = U U^T, U = K_nm L^-T (K_mm = L L^T), so that C0 = U U^T + s^2 I is inverted by
Woodbury's identity with B = s^2 I_m + U^T U, and the evidence is Titsias' (2009) collapsed bound,
the DTC marginal less 3 tr(K - Q) / (2 s^2): the trace term does not depend on theta, so the bound
holds with theta integrated, and it is the exact log Z when the inducing inputs are the rows. Every
sum over rows (U^T U, U^T J_a, U^T y_a, J^T J, J^T y, y^T y) is accumulated in chunks, per fold, so
time is O(n m^2) and memory O(chunk m) whatever n; a fold's sums are the totals less its own, and its
prediction is the projected process's mean J_H theta_T + U_H B_T^-1 U_T^T (y_T - J_T theta_T).
The likelihood's per-point weights or a tracker's noise shape (`remaster.noise`) whiten r and J
before this; the GP then lives in the whitened coordinates.

SI inside (m, rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..evidence import CrossValidation, PosteriorMode
from .kernels import Hyperparameters, covariance_with_noise, kernel
from .likelihood import dense_log_evidence, integrated_log_evidence
from .residual import CHUNK, INDUCING, JITTER, evenly_spaced, inducing_count

MAX_ROWS = 3000  # rows up to which the n x n factor is taken (about 2 s per factor at 3000 on two cores)
MAX_NOISE_ROWS = 600  # rows up to which a noise shape is compared with the GP present (3n x 3n factors)
# inducing inputs of the noise comparison above MAX_NOISE_ROWS: the residual GP's own (the model the loop
# corrects with); its sums cost 3n (3m)^2 operations per noise shape
NOISE_INDUCING = INDUCING
NOISE_CHUNK = 1024  # rows per block of those sums (a (3 chunk, 3m) block: 30 MB at m = 400)


@dataclass(frozen=True)
class WithGP:
    """A model's evidence and cross-validation with the residual GP present: log_evidence (nats, up
    to the flat blocks' constant), theta (P,) SI the parameters' posterior mean and std (P,) their
    posterior std with the GP present, cv: the pose-grouped cross-validation (held-out mean squared
    residual per point, m^2, per fold; None when not asked for); method: 'exact' (n x n factors) or
    'titsias' (inducing inputs, module docstring)."""

    log_evidence: float
    theta: np.ndarray
    std: np.ndarray
    cv: CrossValidation | None
    method: str = "exact"


def _factor(q, hyper: Hyperparameters):
    """Cholesky factor (scipy's cho_factor) of C0 = K + s^2 I at readings q (n, N)."""
    import scipy.linalg

    return scipy.linalg.cho_factor(covariance_with_noise(q, hyper), lower=True)


def _generalised_least_squares(factor, jacobian, y, precision) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(theta (P,), A (P, P), b (P,)) of y (n, 3) = J theta + GP + noise under C0 = factor, J
    (n, 3, P), prior precision (P,) (0: flat)."""
    import scipy.linalg

    solved_j = scipy.linalg.cho_solve(factor, jacobian.reshape(len(y), -1)).reshape(jacobian.shape)
    a = np.einsum("nap,naq->pq", jacobian, solved_j) + np.diag(precision)
    b = np.einsum("nap,na->p", solved_j, y)
    return np.linalg.solve(a, b), a, b


def with_gp(mode: PosteriorMode, q, hyper: Hyperparameters, folds=None) -> WithGP:
    """The model at `mode` (its linearisation, module docstring) with the residual GP of hyper,
    on readings q (n, N) rad, its evidence and its cross-validation over folds (n,) (None: no
    cross-validation, cv None). A noise shape's whitening adds its log-determinant
    (`BlockModel.noise_log_det`) to the evidence, as in the Laplace evidence."""
    import scipy.linalg

    q = np.asarray(q, dtype=float)
    n, p = mode.model.n_points, len(mode.theta)
    if n > MAX_ROWS:
        return sparse_with_gp(mode, q, hyper, folds)
    jacobian = mode.jacobian.reshape(n, 3, p)
    y = mode.model.whitened(mode.residuals) + (mode.jacobian @ mode.theta).reshape(n, 3)
    precision = np.asarray(mode.model._prior_precision, dtype=float)
    factor = _factor(q, hyper)
    theta, a, b = _generalised_least_squares(factor, jacobian, y, precision)
    solved_y = scipy.linalg.cho_solve(factor, y)
    log_det_c0 = 2.0 * float(np.sum(np.log(np.diag(factor[0]))))
    log_evidence = integrated_log_evidence(
        float(np.sum(y * solved_y)), a, b, 3.0 * log_det_c0, 3 * n, precision
    ) + float(mode.model.noise_log_det)
    std = np.sqrt(np.diag(np.linalg.inv(a)))

    if folds is None:
        return WithGP(float(log_evidence), theta, std, None)
    folds = np.asarray(folds)
    mse, points = [], []
    for fold in np.unique(folds):
        train, held = folds != fold, folds == fold
        factor_t = _factor(q[train], hyper)
        theta_t, _, _ = _generalised_least_squares(factor_t, jacobian[train], y[train], precision)
        trend = jacobian @ theta_t
        left = scipy.linalg.cho_solve(factor_t, y[train] - trend[train])
        predicted = trend[held] + kernel(q[held], q[train], hyper) @ left
        mse.append(float(np.mean(np.sum((y[held] - predicted) ** 2, axis=1))))
        points.append(int(held.sum()))
    return WithGP(float(log_evidence), theta, std, CrossValidation(np.array(mse), np.array(points)))


def noise_shape_log_evidence(mode: PosteriorMode, q, hyper: Hyperparameters, shapes) -> float:
    """log Z of the model at `mode` (isotropic noise; its linearisation, module docstring) with the
    residual GP of hyper (lengthscales and signal; its noise_std not used) and the noise of shapes
    (n, 3, 3) m^2, the covariance of each row's noise in the coordinates of the mode's residuals:
    the noise shape compared with the GP present. Dense in 3n: up to `MAX_NOISE_ROWS` rows."""
    n = mode.model.n_points
    if n > MAX_NOISE_ROWS:
        raise ValueError(f"{n} rows: a noise shape is compared with the GP present up to {MAX_NOISE_ROWS} rows")
    y = mode.model.whitened(mode.residuals).ravel() + mode.jacobian @ mode.theta
    covariance = np.kron(kernel(np.asarray(q, dtype=float), np.asarray(q, dtype=float), hyper), np.eye(3))
    blocks = np.asarray(shapes, dtype=float)
    for i in range(n):
        covariance[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] += blocks[i]
    return dense_log_evidence(y, mode.jacobian, np.asarray(mode.model._prior_precision, dtype=float), covariance)


@dataclass
class _Sums:
    """Sums over a set of rows for the inducing-input form (module docstring): uu (m, m) U^T U,
    uj (3, m, P) U^T J_a, uy (3, m) U^T y_a, jj (P, P) sum_a J_a^T J_a, jy (P,), yy, uu_trace
    sum_i |u_i|^2 (tr Q) and the row count n."""

    uu: np.ndarray
    uj: np.ndarray
    uy: np.ndarray
    jj: np.ndarray
    jy: np.ndarray
    yy: float = 0.0
    uu_trace: float = 0.0
    n: int = 0

    @classmethod
    def zero(cls, m: int, p: int) -> _Sums:
        return cls(np.zeros((m, m)), np.zeros((3, m, p)), np.zeros((3, m)), np.zeros((p, p)), np.zeros(p))

    def add(self, u, jacobian, y) -> None:
        """Rows u (k, m), jacobian (k, 3, P), y (k, 3)."""
        self.uu += u.T @ u
        self.uj += np.einsum("km,kap->amp", u, jacobian)
        self.uy += (u.T @ y).T
        self.jj += np.einsum("kap,kaq->pq", jacobian, jacobian)
        self.jy += np.einsum("kap,ka->p", jacobian, y)
        self.yy += float(np.sum(y * y))
        self.uu_trace += float(np.sum(u * u))
        self.n += len(u)

    def plus(self, other: _Sums, sign: float = 1.0) -> _Sums:
        return _Sums(*(getattr(self, f) + sign * getattr(other, f) for f in _Sums.__dataclass_fields__))

    def minus(self, other: _Sums) -> _Sums:
        return self.plus(other, -1.0)


class _Inducing:
    """U = K_nm L^-T at any rows, for m inducing inputs evenly spaced over q (n, N)."""

    def __init__(self, q, hyper: Hyperparameters, inducing: int):
        self.points, self.hyper = q[evenly_spaced(len(q), inducing)], hyper
        k_mm = kernel(self.points, self.points, hyper)
        k_mm[np.diag_indices(len(k_mm))] += JITTER * hyper.signal_std**2
        self.factor = np.linalg.cholesky(k_mm)

    def u(self, q) -> np.ndarray:
        import scipy.linalg

        return scipy.linalg.solve_triangular(self.factor, kernel(self.points, q, self.hyper), lower=True).T


def _sparse_solution(sums: _Sums, noise2: float, precision) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """From one set's sums: theta (P,) = A^-1 b, A (P, P), y^T C0^-1 y and the factor of B (m, m)
    (scipy's cho_factor), C0 = U U^T + noise2 I."""
    import scipy.linalg

    b_factor = scipy.linalg.cho_factor(noise2 * np.eye(len(sums.uu)) + sums.uu, lower=True)
    solved_uj = scipy.linalg.cho_solve(b_factor, sums.uj.transpose(1, 0, 2).reshape(len(sums.uu), -1))
    solved_uj = solved_uj.reshape(len(sums.uu), 3, -1).transpose(1, 0, 2)  # (3, m, P): B^-1 U^T J_a
    solved_uy = scipy.linalg.cho_solve(b_factor, sums.uy.T).T  # (3, m)
    a = (sums.jj - np.einsum("amp,amq->pq", sums.uj, solved_uj)) / noise2 + np.diag(precision)
    b = (sums.jy - np.einsum("amp,am->p", sums.uj, solved_uy)) / noise2
    quadratic = (sums.yy - float(np.sum(sums.uy * solved_uy))) / noise2
    return np.linalg.solve(a, b), a, quadratic, b_factor


def _fold_sums(q, jacobian, y, basis: _Inducing, labels) -> list[_Sums]:
    """Per fold (labels (n,) 0..F-1) the sums over its rows, accumulated CHUNK rows at a time."""
    per_fold = [_Sums.zero(len(basis.points), jacobian.shape[-1]) for _ in range(labels.max() + 1)]
    for begin in range(0, len(q), CHUNK):
        rows = slice(begin, begin + CHUNK)
        u = basis.u(q[rows])
        for f in np.unique(labels[rows]):
            at = labels[rows] == f
            per_fold[f].add(u[at], jacobian[rows][at], y[rows][at])
    return per_fold


def _titsias(total: _Sums, hyper: Hyperparameters, precision) -> tuple[float, np.ndarray, np.ndarray]:
    """(Titsias' bound on log Z with theta integrated, the flat parameters' constant left out and no
    noise shape; theta (P,); A (P, P)) from the sums over every row."""
    noise2, n, m = hyper.noise_std**2, total.n, len(total.uu)
    theta, a, quadratic, b_factor = _sparse_solution(total, noise2, precision)
    log_det_c0 = (n - m) * np.log(noise2) + 2.0 * float(np.sum(np.log(np.diag(b_factor[0]))))
    trace = max(n * hyper.signal_std**2 - total.uu_trace, 0.0)  # tr(K - Q)
    bound = integrated_log_evidence(quadratic, a, a @ theta, 3.0 * log_det_c0, 3 * n, precision)
    return float(bound - 3.0 * trace / (2.0 * noise2)), theta, a


def titsias_log_evidence(q, y, jacobian, precision, hyper: Hyperparameters, inducing: int | None = None) -> float:
    """Titsias' bound on log Z (module docstring) of y (n, 3) m = J theta + f + e at readings q
    (n, N) rad, jacobian (n, 3, P), theta integrated under precision (P,) (0: flat), f the GP of
    `hyper` through `inducing` inducing inputs (None: as many as it needs, `residual.inducing_count`)
    evenly spaced over q."""
    q = np.asarray(q, dtype=float)
    basis = _Inducing(q, hyper, inducing_count(q, hyper, INDUCING) if inducing is None else inducing)
    total = _fold_sums(q, np.asarray(jacobian, dtype=float), np.asarray(y, dtype=float), basis, np.zeros(len(q), int))
    return _titsias(total[0], hyper, np.asarray(precision, dtype=float))[0]


def sparse_with_gp(mode: PosteriorMode, q, hyper: Hyperparameters, folds=None, inducing: int | None = None) -> WithGP:
    """`with_gp` through `inducing` inducing inputs (module docstring; None: as many as the GP needs,
    `residual.inducing_count`): Titsias' bound as the evidence, the projected process's mean as each
    fold's prediction; method 'titsias'."""
    import scipy.linalg

    q = np.asarray(q, dtype=float)
    n, p = mode.model.n_points, len(mode.theta)
    jacobian = mode.jacobian.reshape(n, 3, p)
    y = mode.model.whitened(mode.residuals) + (mode.jacobian @ mode.theta).reshape(n, 3)
    precision = np.asarray(mode.model._prior_precision, dtype=float)
    noise2 = hyper.noise_std**2
    basis = _Inducing(q, hyper, inducing_count(q, hyper, INDUCING) if inducing is None else inducing)
    labels = np.zeros(n, int) if folds is None else np.unique(np.asarray(folds), return_inverse=True)[1].ravel()
    per_fold = _fold_sums(q, jacobian, y, basis, labels)
    total = per_fold[0]
    for other in per_fold[1:]:
        total = total.plus(other)
    bound, theta, a = _titsias(total, hyper, precision)
    log_evidence = bound + float(mode.model.noise_log_det)
    std = np.sqrt(np.diag(np.linalg.inv(a)))
    if folds is None:
        return WithGP(float(log_evidence), theta, std, None, "titsias")
    trained = []  # per fold: theta_T and B_T^-1 U_T^T (y_T - J_T theta_T) (3, m)
    for own in per_fold:
        train = total.minus(own)
        theta_t, _, _, factor_t = _sparse_solution(train, noise2, precision)
        left = train.uy - np.einsum("amp,p->am", train.uj, theta_t)
        trained.append((theta_t, scipy.linalg.cho_solve(factor_t, left.T)))
    squares = np.zeros(len(per_fold))
    for begin in range(0, n, CHUNK):
        rows = slice(begin, begin + CHUNK)
        u = basis.u(q[rows])
        for f in np.unique(labels[rows]):
            at = labels[rows] == f
            theta_t, weights = trained[f]
            predicted = jacobian[rows][at] @ theta_t + u[at] @ weights
            squares[f] += float(np.sum((y[rows][at] - predicted) ** 2))
    points = np.array([s.n for s in per_fold])
    return WithGP(float(log_evidence), theta, std, CrossValidation(squares / points, points), "titsias")


class ShapedNoiseEvidence:
    """log Z of the model at `mode` (isotropic noise; its linearisation) with the residual GP of
    hyper (lengthscales and signal) through `inducing` inducing inputs, and the noise sigma^2 T_i,
    T_i (n, 3, 3) the unit shapes (`noise_shape_log_evidence`'s, over sigma^2), as a function of
    sigma: the noise shape compared with the GP present above `MAX_NOISE_ROWS` rows.

    With V = U (x) I3 (3n x 3m) and C = sigma^2 T + V V^T, Woodbury's identity leaves every sum over
    rows free of sigma: M = V^T T^-1 V (3m x 3m), V^T T^-1 J, V^T T^-1 y, J^T T^-1 J, J^T T^-1 y,
    y^T T^-1 y, log|T| and Titsias' trace sum_i (k_ii - q_ii) tr T_i^-1 are accumulated once, in
    chunks (O(n m^2) time, O(chunk m) memory), M is diagonalised once, and each sigma then costs
    O(m P^2): (sigma^2 I + M)^-1 is diagonal in M's eigenvectors."""

    def __init__(self, mode: PosteriorMode, q, hyper: Hyperparameters, unit_shapes, inducing: int | None = None):
        q, shapes = np.asarray(q, dtype=float), np.asarray(unit_shapes, dtype=float)
        n, p = mode.model.n_points, len(mode.theta)
        jacobian = mode.jacobian.reshape(n, 3, p)
        y = mode.model.whitened(mode.residuals) + (mode.jacobian @ mode.theta).reshape(n, 3)
        basis = _Inducing(q, hyper, NOISE_INDUCING if inducing is None else inducing)
        m = len(basis.points)
        self.m, self.n, self.precision = m, n, np.asarray(mode.model._prior_precision, dtype=float)
        big_m, xj, xy = np.zeros((3 * m, 3 * m)), np.zeros((3 * m, p)), np.zeros(3 * m)
        self.jj, self.jy, self.yy, self.log_det_t, self.trace = np.zeros((p, p)), np.zeros(p), 0.0, 0.0, 0.0
        for begin in range(0, n, NOISE_CHUNK):
            rows = slice(begin, begin + NOISE_CHUNK)
            u = basis.u(q[rows])
            factor = np.linalg.cholesky(np.linalg.inv(shapes[rows]))  # T_i^-1 = L_i L_i^T
            lt = np.swapaxes(factor, 1, 2)  # L_i^T
            x = np.einsum("ij,iab->iajb", u, lt).reshape(-1, 3 * m)  # X_i = u_i^T (x) L_i^T, (3k, 3m)
            j_w, y_w = np.einsum("iab,ibp->iap", lt, jacobian[rows]), np.einsum("iab,ib->ia", lt, y[rows])
            big_m += x.T @ x
            xj += x.T @ j_w.reshape(-1, p)
            xy += x.T @ y_w.ravel()
            self.jj += np.einsum("iap,iaq->pq", j_w, j_w)
            self.jy += np.einsum("iap,ia->p", j_w, y_w)
            self.yy += float(np.sum(y_w**2))
            self.log_det_t += float(np.sum(np.linalg.slogdet(shapes[rows])[1]))
            unexplained = np.maximum(hyper.signal_std**2 - np.sum(u * u, axis=1), 0.0)  # k_ii - q_ii
            self.trace += float(np.sum(unexplained * np.sum(factor**2, axis=(1, 2))))  # tr T^-1 = |L|_F^2
        self.values, vectors = np.linalg.eigh(big_m)
        self.values = np.maximum(self.values, 0.0)
        self.xj, self.xy = vectors.T @ xj, vectors.T @ xy

    def __call__(self, sigma: float) -> float:
        s2 = sigma**2
        inverse = 1.0 / (s2 + self.values)
        a = (self.jj - (self.xj.T * inverse) @ self.xj) / s2 + np.diag(self.precision)
        b = (self.jy - (self.xj.T * inverse) @ self.xy) / s2
        quadratic = (self.yy - float(np.sum(self.xy**2 * inverse))) / s2
        log_det_c = 3 * (self.n - self.m) * np.log(s2) + self.log_det_t + float(np.sum(np.log(s2 + self.values)))
        return integrated_log_evidence(quadratic, a, b, log_det_c, 3 * self.n, self.precision) - 0.5 * self.trace / s2
