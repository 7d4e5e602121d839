"""What no parametric effect explains: a Gaussian process over the joint angles.

After the parametric effects, the residual r(q) (3,) m at joint readings q (N,) rad is modelled as

    r(q) = g(q) + e,   g_x, g_y, g_z ~ GP(0, k) independent with one kernel,   e ~ N(0, noise^2 I3),

k the squared exponential on the circle of each joint (`kernels`). The residual is expressed in the
ROBOT frame (rotated back by the fit's registration), so the correction travels with the robot.

Hyperparameters (l_j, s, noise) maximise the exact marginal likelihood of at most `subset` rows
evenly spaced over the data (analytic gradient, L-BFGS-B in logs, two starts): O(subset^3)
whatever n. Prediction uses all n rows through m inducing inputs (the same kind of
subset; as many as leave at most `UNEXPLAINED` of the prior variance unexplained at the other rows,
`inducing_count`: a fixed count fails on a dense grid of short lengthscales), the DTC /
projected-process approximation (Seeger, Williams & Lawrence 2003;
Quinonero-Candela & Rasmussen 2005): O(n m^2) time and O(chunk m) memory. Far from every inducing
input the mean returns to zero and the variance to s^2: the correction does not extrapolate, it
says it does not know. The evidence the loop decides with is not the DTC
likelihood (which can be far above or below the exact one): `evidence_gain`.

Relevance of joint j: its measured range (max - min of q_j) over l_j, the number of lengthscales
the data cross along it; the residual "depends on" the joints where it is at least
`RELEVANT_RANGE`.

SI inside (m, rad).
"""

from __future__ import annotations

import collections
import dataclasses
import hashlib
import math

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from .kernels import LENGTH_BOUNDS, Hyperparameters, at_bounds, circle_distances, kernel, turned_joints
from .likelihood import LOG_2PI, negative_log_marginal_likelihood

SUBSET = 600  # rows for the hyperparameters (exact marginal likelihood)
INDUCING = 400  # the fewest inducing inputs for prediction (and the evidence's bound above `evidence_gain.EXACT_ROWS`)
# inducing inputs are added (doubling from INDUCING) until at most this share of the prior variance s^2 is
# left unexplained, on average, at rows that are not inducing inputs: on a dense grid of short lengthscales
# 400 evenly spaced ones leave most of it, and Titsias' bound then pays n * share * s^2 / (2 noise^2) per
# axis, which sank a GP that halves the held-out error (benchmarks/bench_gp_size.py)
UNEXPLAINED = 0.02
MAX_INDUCING = 2400  # the most: (CHUNK, 2400) covariance blocks (~160 MB each) and 2400^3 factors
PROBE_ROWS = 2000  # rows, evenly spaced, on which the unexplained share is measured
CHUNK = 8192  # rows per block when accumulating over all n
RELEVANT_RANGE = 0.5  # lengthscales crossed over the measured range: the residual depends on that joint
SIGNAL_BOUNDS = (1e-4, 10.0)  # s over rms(r)
NOISE_BOUNDS = (1e-3, 10.0)  # noise over rms(r)
DRAW_BLOCK = 2000  # readings drawn jointly at once: a (2000, 2000) factor, 32 MB
JITTER = 1e-8  # relative to s^2, for the inducing covariance's Cholesky factor


def _blocks(q: np.ndarray) -> range:
    """The first reading of each block of CHUNK readings of q (n, N)."""
    return range(0, len(q), CHUNK)


def evenly_spaced(n: int, count: int) -> np.ndarray:
    """At most `count` row indices spread evenly over n rows (all of them when n <= count):
    deterministic, and representative when rows are in measurement order."""
    return np.arange(n) if n <= count else np.unique(np.linspace(0, n - 1, count).round().astype(int))


def unexplained_share(q, hyper: Hyperparameters, inducing: int) -> float:
    """The mean of 1 - q_ii / k_ii, the share of the prior variance that `inducing` evenly spaced
    inducing inputs leave unexplained, over up to PROBE_ROWS evenly spaced rows of q (n, N) rad that
    are not inducing inputs (0 when every row is one)."""
    import scipy.linalg

    q = np.asarray(q, dtype=float)
    rows = evenly_spaced(len(q), inducing)
    probe = q[np.setdiff1d(evenly_spaced(len(q), PROBE_ROWS), rows)]
    if not len(probe):
        return 0.0
    k_mm = kernel(q[rows], q[rows], hyper)
    k_mm[np.diag_indices(len(rows))] += JITTER * hyper.signal_std**2
    whitened = scipy.linalg.solve_triangular(
        np.linalg.cholesky(k_mm), kernel(q[rows], probe, hyper), lower=True, check_finite=False
    )
    return 1.0 - float(np.mean(np.sum(whitened**2, axis=0))) / hyper.signal_std**2


def inducing_count(q, hyper: Hyperparameters, at_least: int = INDUCING, at_most: int = MAX_INDUCING) -> int:
    """How many evenly spaced inducing inputs the GP of `hyper` needs at readings q (n, N) rad: from
    `at_least`, doubled until `unexplained_share` is at most UNEXPLAINED, or `at_most` (or every
    row) is reached."""
    n = len(q)
    m = min(at_least, n)
    while m < min(n, at_most) and unexplained_share(q, hyper, m) > UNEXPLAINED:
        m = min(2 * m, n, at_most)
    return m


# The hyperparameters of the last few fits, by a digest of their inputs: the loop fits the same GP on
# the same residuals more than once (as a candidate, then for its time blocks and its backward pass)
_FITTED: collections.OrderedDict[bytes, Hyperparameters] = collections.OrderedDict()
_FITTED_KEPT = 8


def fit_hyperparameters(q, residuals, subset: int = SUBSET, start: Hyperparameters | None = None) -> Hyperparameters:
    """Type-II maximum likelihood of (l_j, s, noise) on at most `subset` evenly spaced rows of q
    (n, N) rad and residuals (n, 3) m; from `start` when given (one start), else from a smooth
    and a wiggly start. The same inputs give the same fit, found again rather than refitted."""
    q, y = np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(residuals, dtype=float)
    started = None if start is None else (start.signal_std, start.noise_std)  # a float's repr is exact
    digest = hashlib.sha256(repr((q.shape, y.shape, subset, started)).encode())
    for array in (q, y) if start is None else (q, y, np.asarray(start.lengthscales, dtype=float)):
        digest.update(array.tobytes())
    key = digest.digest()
    if key not in _FITTED:
        _FITTED[key] = _fitted_hyperparameters(q, y, subset, start)
        if len(_FITTED) > _FITTED_KEPT:
            _FITTED.popitem(last=False)
    found = _FITTED[key]
    return dataclasses.replace(found, lengthscales=found.lengthscales.copy())


def _fitted_hyperparameters(
    q: np.ndarray, y: np.ndarray, subset: int, start: Hyperparameters | None
) -> Hyperparameters:
    """`fit_hyperparameters`, computed."""
    import scipy.optimize

    rows = evenly_spaced(len(q), subset)
    q_s, y_s = q[rows], y[rows]
    spread = np.ptp(q, axis=0)
    turned = turned_joints(q)
    unit = float(np.sqrt(np.mean(y_s**2))) or 1.0  # work in units of the residual's size
    y_s = y_s / unit
    distances = circle_distances(q_s[:, turned])
    span = np.clip(spread[turned], LENGTH_BOUNDS[0], LENGTH_BOUNDS[1])
    bounds = [tuple(np.log(LENGTH_BOUNDS))] * int(turned.sum()) + [
        (math.log(SIGNAL_BOUNDS[0]), math.log(SIGNAL_BOUNDS[1])),
        (math.log(NOISE_BOUNDS[0]), math.log(NOISE_BOUNDS[1])),
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
            negative_log_marginal_likelihood, x0, args=(distances, y_s), jac=True, method="L-BFGS-B", bounds=bounds
        )
        if best is None or result.fun < best.fun:
            best = result
    lengths = np.full(q.shape[1], np.inf)
    lengths[turned] = np.exp(best.x[: int(turned.sum())])
    names = [f"q{j + 1} lengthscale" for j in np.flatnonzero(turned)] + ["signal_std", "noise_std"]
    return Hyperparameters(
        lengths, unit * math.exp(best.x[-2]), unit * math.exp(best.x[-1]), at_bounds(best.x, bounds, names)
    )


class ResidualGP:
    """The GP conditioned on residuals (n, 3) m at readings q (n, N) rad with given hyperparameters,
    through `inducing` inducing inputs (DTC). `mean`, `variance` at any readings; `log_likelihood`
    of the training residuals (DTC)."""

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
        """Posterior mean of g (n*, 3) m at readings q (n*, N) rad (CHUNK readings at a time, so that
        the (n*, inducing) covariances never exist at once)."""
        q = np.asarray(q, dtype=float)
        return np.concatenate(
            [np.empty((0, 3))]
            + [kernel(q[begin : begin + CHUNK], self.inducing, self.hyper) @ self.weights for begin in _blocks(q)]
        )

    def variance(self, q) -> np.ndarray:
        """Posterior variance of each component of g (n*,) m^2 at readings q (n*, N), without the
        noise: s^2 far from the data (CHUNK readings at a time)."""
        import scipy.linalg

        q = np.asarray(q, dtype=float)
        out = np.empty(len(q))
        for begin in _blocks(q):
            k_sm = kernel(q[begin : begin + CHUNK], self.inducing, self.hyper)
            explained = np.sum(k_sm.T * scipy.linalg.cho_solve(self._k_factor, k_sm.T), axis=0)
            left = self.hyper.noise_std**2 * np.sum(k_sm.T * scipy.linalg.cho_solve(self._a_factor, k_sm.T), axis=0)
            out[begin : begin + CHUNK] = np.maximum(self.hyper.signal_std**2 - explained + left, 0.0)
        return out

    def draws(self, q, count: int, rng: np.random.Generator) -> np.ndarray:
        """`count` draws (count, n*, 3) m of g at readings q (n*, N), jointly across the readings, so
        that a statistic over readings (a p95, an RMS) is one of a function the robot could have: the
        part the inducing inputs carry, K*m A^-1/2 z (z ~ N(0, I) per inducing input and axis),
        plus the part they do not, K** - Q** (Q** = K*m Kmm^-1 Km*), drawn jointly within blocks of
        DRAW_BLOCK readings (a Cholesky factor each; independent between blocks, which only a
        campaign of more readings than that sees). Each reading's marginal is `mean`, `variance`."""
        import scipy.linalg

        q = np.asarray(q, dtype=float)
        k_sm = kernel(q, self.inducing, self.hyper)
        shared = scipy.linalg.solve_triangular(self._a_factor[0], k_sm.T, lower=True)  # (m, n*): K*m A^-1 Km* = B^T B
        z = rng.standard_normal((count, len(self.inducing), 3))
        out = self.mean(q)[None] + self.hyper.noise_std * _applied_to_draws(shared.T, z)
        whitened = scipy.linalg.solve_triangular(self._k_factor[0], k_sm.T, lower=True)  # Q** = W^T W
        out += field_draws(
            q,
            self.hyper,
            count,
            rng,
            explained=lambda block: whitened[:, block].T @ whitened[:, block],
        )
        return out


def field_draws(q, hyper: Hyperparameters, count: int, rng: np.random.Generator, explained=None) -> np.ndarray:
    """`count` draws (count, n, 3) m of a zero-mean field over readings q (n, N) rad of kernel `hyper`
    (its signal; three axes alike and independent), jointly within blocks of DRAW_BLOCK readings (a
    Cholesky factor each; independent between blocks), so that a statistic over the readings (a p95)
    is one of a field the robot could have. explained(block): a covariance (b, b) the caller draws
    otherwise, taken off the kernel's (the inducing inputs' part of a fitted GP)."""
    q = np.asarray(q, dtype=float)
    out = np.zeros((count, len(q), 3))
    for begin in range(0, len(q), DRAW_BLOCK):
        block = slice(begin, begin + DRAW_BLOCK)
        rest = kernel(q[block], q[block], hyper)
        if explained is not None:
            rest = rest - explained(block)
        rest[np.diag_indices(len(rest))] += JITTER * hyper.signal_std**2
        try:
            factor = np.linalg.cholesky(rest)
        except np.linalg.LinAlgError:  # round-off (or readings repeated) made it indefinite: the nearest PSD factor
            values, vectors = np.linalg.eigh(rest)
            factor = vectors * np.sqrt(np.clip(values, 0.0, None))
        out[:, block] = _applied_to_draws(factor, rng.standard_normal((count, len(rest), 3)))
    return out


def model_error_draws(
    size: float, field: Hyperparameters | None, q, count: int, rng: np.random.Generator
) -> np.ndarray:
    """`count` draws (count, n, 3) m of a model error of `size` per axis (m) at readings q (n, N): one
    field across the readings of kernel `field` (`field_draws`; its signal std is the size), or, without
    one, independent per axis and reading. Each reading's marginal is N(0, size^2) per axis either way."""
    if field is None:
        return size * rng.standard_normal((count, len(q), 3))
    return field_draws(q, field, count, rng)


def _applied_to_draws(matrix: np.ndarray, z: np.ndarray) -> np.ndarray:
    """matrix (a, b) applied to each draw of z (k, b, c): (k, a, c), as one matrix product (the
    equivalent einsum loops in C without BLAS, about 80x slower at 2000 draws of 1000 readings)."""
    count, rows, axes = z.shape
    flat = matrix @ z.transpose(1, 0, 2).reshape(rows, count * axes)
    return flat.reshape(len(matrix), count, axes).transpose(1, 0, 2)


def titsias_bound(q, residuals, hyper: Hyperparameters, inducing: int) -> float:
    """Titsias' (2009) collapsed variational lower bound on log p(r) (nats) of residuals (n, 3) m at
    readings q (n, N) rad through `inducing` evenly spaced inducing inputs: the DTC log likelihood
    less outputs * tr(K - Q) / (2 noise^2), Q = K_nm K_mm^-1 K_mn. Equals the exact value when the
    inducing inputs are the rows."""
    import scipy.linalg

    q, y = np.asarray(q, dtype=float), np.asarray(residuals, dtype=float)
    gp = ResidualGP(q, y, hyper, inducing)
    projected = 0.0
    for begin in range(0, len(q), CHUNK):
        k_mn = kernel(gp.inducing, q[begin : begin + CHUNK], hyper)
        projected += float(np.sum(k_mn * scipy.linalg.cho_solve(gp._k_factor, k_mn)))
    trace = max(len(q) * hyper.signal_std**2 - projected, 0.0)
    return gp.log_likelihood - y.shape[1] * trace / (2.0 * hyper.noise_std**2)


def relevance(hyper: Hyperparameters, q) -> np.ndarray:
    """(N,) measured range of each joint over its lengthscale (0 for a joint never turned)."""
    spread = np.ptp(np.asarray(q, dtype=float), axis=0)
    return np.where(hyper.turned, spread / np.where(hyper.turned, hyper.lengthscales, 1.0), 0.0)
