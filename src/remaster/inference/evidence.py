"""A block model under its priors: MAP, Laplace covariance, Laplace evidence and pose-grouped
cross-validation. The loop closure decides with these, never with the validation set.

The log-posterior is the paper's plus the extension blocks' Gaussian priors N(0, tau_k^2)
(`remaster.robot.priors`); sigma keeps Jeffreys' prior (the paper's sigma^-2, so sigma^-(3n+2) in all):

    log p(theta, sigma | y) = -(3n + 2) log sigma - SS(theta) / (2 sigma^2) - sum_k theta_k^2 / (2 tau_k^2)

In u = log sigma the density gains a factor sigma, and the MAP in (theta, u) is found by
alternating least squares in the stacked residuals [r(theta); sigma theta_k / tau_k] (their sum
of squares is SS + sigma^2 sum (theta_k / tau_k)^2, the posterior's theta-part times 2 sigma^2)
with sigma^2 = SS / (3n + 1), until sigma settles.

Laplace evidence, up to a constant common to every model of the same data and base blocks
(the flat priors of the registration and zero-offsets and Jeffreys' on sigma are improper: their
constants cancel in a difference between two candidates):

    log Z = log L(theta*, sigma*) + sum_k log N(theta*_k; 0, tau_k^2) + log sigma*^-1
            + (d / 2) log 2 pi - 1/2 log det H,

d = P + 1 and H the negative Hessian of the log-posterior in (theta, u), Gauss-Newton in theta:
H_tt = J^T J / sigma^2 + diag(1 / tau^2), H_tu = 2 J^T r / sigma^2 (J = d predicted / d theta),
H_uu = 2 SS / sigma^2. An added parameter pays its Occam factor (prior width over posterior width)
unless the fit gains more; a prior much wider than the effect costs evidence, so priors of physical
size matter.

Cross-validation by pose: K folds of whole poses (the configurations of one Cartesian pose share
much of their residual, so folds of single rows would flatter a model). Each fold's fit is one
Gauss-Newton step from the full MAP on the other folds' rows, registration included (the
registration is refitted in each fold), and its error is the held-out rows' mean squared
residual evaluated with the full model: an approximation of refitting from scratch that is exact
for a linear model and close for these near-linear ones, at the cost of one solve per fold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np  # scipy and emcee are imported in the functions that use them (test_architecture: light readers)

from . import chi_square
from .blocks import BlockModel
from .gp.likelihood import LOG_2PI
from .identifiability import JACOBIAN_STEP
from .least_squares import least_squares_mode

MAX_SIGMA_ROUNDS = 20
SIGMA_TOLERANCE = 1e-4  # relative change of sigma at which the MAP has settled (sigma only weighs the priors)


@dataclass(frozen=True, eq=False)
class PosteriorMode:
    """MAP of a block model under its priors and the Laplace approximation around it.

    theta (P,) SI free parameters; sigma (m); covariance (P + 1, P + 1) of (theta, sigma);
    jacobian (3n, P) of the (whitened, `remaster.noise`) predictions at theta; residuals (n, 3) m,
    not whitened; log_evidence (nats, up to the constant common to models of the same data and
    base); sum_squares (m^2) of the whitened residuals."""

    model: BlockModel
    theta: np.ndarray
    sigma: float
    covariance: np.ndarray
    jacobian: np.ndarray
    residuals: np.ndarray
    log_evidence: float
    sum_squares: float

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.names

    @property
    def n_residuals(self) -> int:
        return self.residuals.size

    @property
    def std(self) -> np.ndarray:
        """(P,) Laplace standard deviations of the free parameters, SI."""
        return np.sqrt(np.diag(self.covariance)[:-1])

    @property
    def sigma_std(self) -> float:
        return float(math.sqrt(self.covariance[-1, -1]))

    def sampler_start(self) -> dict:
        """What `posterior_sampling.sample` reads: MAP, covariance of theta and sigma's std."""
        return {
            "theta_map": self.theta.tolist(),
            "sigma_map": self.sigma,
            "covariance": self.covariance[:-1, :-1].tolist(),
            "sigma_std": self.sigma_std,
        }

    def bic(self) -> float:
        """k ln(SS / k) + p ln k, p = free parameters + sigma: the Gaussian likelihood maximised
        over sigma, for reference beside the evidence."""
        k = self.n_residuals
        return k * math.log(self.sum_squares / k) + (len(self.theta) + 1) * math.log(k)


def posterior_mode(model: BlockModel, start=None) -> PosteriorMode:
    """MAP of the model's posterior from `start` (P,) SI (default 0) and its Laplace approximation."""
    theta = np.zeros(len(model.names)) if start is None else np.asarray(start, dtype=float)
    k = 3 * model.n_rows
    sigma = math.sqrt(float(np.sum(model.weighted_residuals(theta) ** 2)) / (k + 1))
    for _ in range(MAX_SIGMA_ROUNDS):

        def stacked(t, s=sigma):
            """Residuals (K,) at t (P,), or (m, K) at a stack (m, P)."""
            weighted = model.weighted_residuals(t)
            return np.concatenate(
                [weighted.reshape(weighted.shape[:-2] + (-1,)), s * model.prior_residuals(t)], axis=-1
            )

        # Levenberg-Marquardt (MINPACK): no SVD of the whole Jacobian per step, unlike 'trf'
        theta = least_squares_mode(
            stacked, theta, model.scale, lambda t: forward_differences(stacked, t), method="lm"
        ).x
        previous, sigma = sigma, math.sqrt(float(np.sum(model.weighted_residuals(theta) ** 2)) / (k + 1))
        if abs(sigma - previous) <= SIGMA_TOLERANCE * sigma:
            break
    return laplace_at(model, theta, sigma)


def forward_differences(function, x) -> np.ndarray:
    """Jacobian (K, P) of function (P,) -> (K,) at x by scipy's default forward differences (step
    sqrt(eps) max(1, |x_i|), signed as x_i, the exactly representable difference as the divisor),
    its P + 1 points evaluated in one call of `function` on a stack (P + 1, P) -> (P + 1, K):
    the block model evaluates a stack a chunk at a time instead of one vector at a time."""
    x = np.asarray(x, dtype=float)
    step = math.sqrt(np.finfo(float).eps) * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
    points = np.tile(x, (len(x) + 1, 1))
    points[np.arange(len(x)), np.arange(len(x))] = x + step
    values = function(points)
    return ((values[:-1] - values[-1]) / ((x + step) - x)[:, None]).T


def laplace_at(model: BlockModel, theta, sigma: float) -> PosteriorMode:
    """The Laplace approximation and evidence at (theta (P,) SI, sigma m), taken as the mode.

    Not `least_squares_laplace`, which approximates another posterior for another use:
    this one is a block model's joint posterior in (theta, log sigma), its priors' precision and
    noise shape (whitened residuals) in the (P + 1)-square Hessian, sigma correlated with theta, at
    the joint mode (sigma^2 = SS / (k + 1), `posterior_mode`); and it gives the log evidence the
    loop compares models by. That one is the paper's flat-prior fit with sigma integrated out
    (s^2 = SS / (k - P), sigma's exact marginal mean and std, an SVD test of what the data
    determine), the start of the paper's samplers, and no evidence."""
    theta = np.asarray(theta, dtype=float)
    residuals = model.residuals(theta)
    r = model.whitened(residuals).ravel()
    sum_squares = float(r @ r)
    jacobian = -model.weighted_jacobian(theta, JACOBIAN_STEP)  # d (whitened) predicted / d theta
    precision = model._prior_precision
    p = len(theta)
    hessian = np.empty((p + 1, p + 1))
    hessian[:p, :p] = jacobian.T @ jacobian / sigma**2 + np.diag(precision)
    hessian[:p, p] = hessian[p, :p] = 2.0 * jacobian.T @ r / sigma**2
    hessian[p, p] = 2.0 * sum_squares / sigma**2
    sign, log_det = np.linalg.slogdet(hessian)
    if sign <= 0:
        raise np.linalg.LinAlgError(
            "the posterior's Hessian is not positive definite at the mode: "
            "a parameter without prior is not determined by the data"
        )
    covariance_u = np.linalg.inv(hessian)
    # (theta, u) -> (theta, sigma): d sigma = sigma du
    jac = np.ones(p + 1)
    jac[p] = sigma
    covariance = covariance_u * np.outer(jac, jac)
    k = r.size
    has_prior = np.isfinite(model.prior_std)
    log_likelihood = -0.5 * k * LOG_2PI - k * math.log(sigma) - sum_squares / (2.0 * sigma**2) + model.noise_log_det
    log_prior = float(
        np.sum(-0.5 * LOG_2PI - np.log(model.prior_std[has_prior]) - 0.5 * theta[has_prior] ** 2 * precision[has_prior])
    ) - math.log(sigma)
    log_evidence = log_likelihood + log_prior + 0.5 * (p + 1) * LOG_2PI - 0.5 * log_det
    return PosteriorMode(model, theta, float(sigma), covariance, jacobian, residuals, float(log_evidence), sum_squares)


# --------------------------------------------------------------------------- cross-validation by pose


def pose_folds(poses, n_folds: int) -> np.ndarray:
    """(n,) fold of each point: whole poses in turn (pose labels sorted, the i-th to fold i mod K),
    so that no pose is split and the folds do not depend on a random draw."""
    labels = np.unique(poses)
    if len(labels) < n_folds:
        raise ValueError(f"{len(labels)} poses cannot make {n_folds} folds of whole poses")
    fold_of = {label: i % n_folds for i, label in enumerate(labels)}
    return np.array([fold_of[p] for p in poses])


# A fold whose held-out RMS per axis is this many times the full fit's sigma (which holds any model
# error the fit has) after its fit was iterated to the fold's own mode has departed: the other folds
# leave a combination almost free, and its error measures that, not the model
DEPARTED_RATIO = 10.0
# A fold whose fit moves a parameter with a prior by more than this many prior standard deviations
# from the full fit has departed as well: a normal prior puts 6e-7 of its mass that far out, and
# leaving out a fifth of the rows moves a determined parameter by a fraction of its posterior width
PRIOR_RANGE = 5.0


@dataclass(frozen=True)
class CrossValidation:
    """Held-out mean squared residual per point (m^2), one per fold (K,), points per fold,
    held_out (n, 3) m: each point's residual under the fit without its fold, noise_inflation:
    what a correct model's pooled held-out mean square is, over its noise variance (3 per point):
    a fit without the fold errs at the fold's rows by its parameters' spread as well as by the
    noise (`cross_validate`); 1 where it is not known (a GP's folds), which never flatters a fit;
    departed (K,) bool: the folds whose fit departed (`DEPARTED_RATIO`, `PRIOR_RANGE`), None
    where none was tested; prior_steps (K,): each fold's largest move of a parameter with a prior
    from the full fit, in prior standard deviations (0 for a model without priors);
    null_cumulants: the first three cumulants of a correct model's pooled held-out sum of squares
    over the noise variance, kept folds (`cross_validate`), None where not known (a GP's folds).
    `rmse` and every decision leave the departed folds out."""

    mse: np.ndarray
    points: np.ndarray
    held_out: np.ndarray | None = None
    noise_inflation: float = 1.0
    departed: np.ndarray | None = None
    prior_steps: np.ndarray | None = None
    null_cumulants: tuple[float, float, float] | None = None

    @property
    def held_out_numbers(self) -> int:
        """How many numbers (3 per point) the kept folds hold out."""
        kept = self.kept if self.kept.any() else np.ones(len(self.mse), bool)
        return int(3 * np.sum(self.points[kept]))

    @property
    def kept(self) -> np.ndarray:
        """(K,) bool: the folds that did not depart."""
        return np.ones(len(self.mse), bool) if self.departed is None else ~np.asarray(self.departed, bool)

    @property
    def rmse(self) -> float:
        """Root of the pooled held-out mean squared residual per point (m), over the kept folds
        (every fold when all departed)."""
        kept = self.kept if self.kept.any() else np.ones(len(self.mse), bool)
        return float(math.sqrt(np.sum(self.mse[kept] * self.points[kept]) / np.sum(self.points[kept])))


def _fold_mode(mode: PosteriorMode, train: np.ndarray) -> np.ndarray:
    """The mode (P,) of the posterior of the rows `train` (n,) bool, the full fit's sigma held
    (it only weighs the priors), iterated by Levenberg-Marquardt from the full fit's mode."""
    model, sigma = mode.model, mode.sigma

    def stacked(t):
        weighted = model.weighted_residuals(t)[..., train, :]
        return np.concatenate(
            [weighted.reshape(weighted.shape[:-2] + (-1,)), sigma * model.prior_residuals(t)], axis=-1
        )

    jacobian = lambda t: forward_differences(stacked, t)  # noqa: E731
    return least_squares_mode(stacked, mode.theta, model.scale, jacobian, method="lm").x


def _prior_steps(model: BlockModel, step: np.ndarray) -> float:
    """The largest |step| (P,) of a parameter with a prior, in its prior standard deviations."""
    finite = np.isfinite(model.prior_std)
    return float(np.max(np.abs(step[finite]) / model.prior_std[finite])) if finite.any() else 0.0


def cross_validate(mode: PosteriorMode, folds: np.ndarray) -> CrossValidation:
    """Pose-grouped K-fold cross-validation of a model at its mode (module docstring); folds (n,).

    With it, the noise inflation of a correct model (`CrossValidation`): a held-out residual is
    e_f - J_f (A^-1 J_t^T e_t) for noise e, A = J_t^T J_t + the priors' precision, so its expected
    sum of squares is s^2 (3 n_f + tr(J_f A^-1 J_t^T J_t A^-1 J_f^T)) in the whitened units of the
    step, pooled over the kept folds; its first three cumulants (`held_out_cumulants`) are the closure
    test's. The priors' pull towards their centre is left out: it biases a held-out prediction where
    the truth lies away from the centre, a model error the closure test may then find. A fold whose
    linear step leaves its held-out RMS per axis above DEPARTED_RATIO times the fit's sigma, or moves
    a parameter beyond PRIOR_RANGE of its prior, is fitted again, iterated to its own mode
    (`_fold_mode`); if it is still beyond either, it has departed (`CrossValidation.departed`)."""
    model, theta, sigma = mode.model, mode.theta, mode.sigma
    jacobian = mode.jacobian.reshape(model.n_points, 3, -1)
    r = model.whitened(mode.residuals)
    precision = model._prior_precision * sigma**2
    mse, points, held, departed, prior_steps = [], [], np.empty_like(r), [], []
    inverses, grams = [], []  # per fold: A^-1 of its fit and G_f = J_f^T J_f of its rows (P x P)
    limit = 3.0 * (DEPARTED_RATIO * sigma) ** 2  # m^2 per point
    for fold in np.unique(folds):
        train = folds != fold
        j_train = jacobian[train].reshape(-1, len(theta))
        lhs = j_train.T @ j_train + np.diag(precision)
        rhs = j_train.T @ r[train].ravel() - precision * theta
        step = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
        held_out = model.residuals(theta + step)[~train]
        points.append(int((~train).sum()))
        j_fold = jacobian[~train].reshape(-1, len(theta))
        inverses.append(np.linalg.pinv(lhs))
        grams.append(j_fold.T @ j_fold)
        fold_theta = theta + step
        if np.mean(np.sum(held_out**2, axis=1)) > limit or _prior_steps(model, step) > PRIOR_RANGE:
            fold_theta = _fold_mode(mode, train)
            held_out = model.residuals(fold_theta)[~train]
        held[~train] = held_out
        mse.append(float(np.mean(np.sum(held_out**2, axis=1))))
        prior_steps.append(_prior_steps(model, fold_theta - theta))
        departed.append(mse[-1] > limit or prior_steps[-1] > PRIOR_RANGE)
    kept = ~np.array(departed, bool) if not all(departed) else np.ones(len(departed), bool)
    numbers = 3 * int(np.sum(np.array(points)[kept]))
    cumulants = held_out_cumulants(
        [inverses[k] for k in np.flatnonzero(kept)], [grams[k] for k in np.flatnonzero(kept)], sum(grams), numbers
    )
    inflation = cumulants[0] / numbers if numbers else 1.0
    return CrossValidation(
        np.array(mse),
        np.array(points),
        held,
        inflation,
        np.array(departed, bool),
        np.array(prior_steps),
        cumulants,
    )


def held_out_cumulants(inverses, grams, total_gram, numbers: int) -> tuple[float, float, float]:
    """The first three cumulants of a correct linear model's pooled held-out sum of squares over the
    noise variance (`cross_validate`), from each kept fold's A_f^-1 and G_f (P x P), G = J^T J over
    every row (total_gram), and the numbers (3 per point) the kept folds hold out.

    Fold f's held-out residual is h_f = e_f - J_f A_f^-1 J_(not f)^T e for noise e ~ N(0, I), so
    Cov(h_f, h_g) = delta_fg I + J_f W_fg J_g^T with W_ff = A_f^-1 (G - G_f) A_f^-1 and, f != g,
    W_fg = A_f^-1 (G - G_f - G_g) A_g^-1 - A_f^-1 - A_g^-1. The sum of squares is sum_i lambda_i
    chi2_1 over that covariance's eigenvalues, which are 1 but for 1 + the eigenvalues of
    M = W Gamma (Gamma = blockdiag G_f, K P x K P): its cumulants 2^(j-1) (j-1)! tr(Cov^j) from
    tr(M), tr(M^2), tr(M^3) whatever the rows. Few rows per parameter make a few large lambda_i: a
    correct model's held-out error is then far from chi-square with 3n degrees of freedom. The truth is
    held fixed and the priors' pull left out (`cross_validate`): taking the truth as a draw from the
    priors instead put the held-out floor of the simulated cyclic campaigns with joint harmonics (28
    coefficients under their priors, 25 configurations) at 1.5-3.3 times their held-out RMS: a test
    without power."""
    k = len(inverses)
    if k == 0:
        return chi_square.cumulants(numbers)
    p = len(total_gram)
    w = np.empty((k * p, k * p))
    for f in range(k):
        for g in range(k):
            rows, cols = slice(f * p, (f + 1) * p), slice(g * p, (g + 1) * p)
            if f == g:
                w[rows, cols] = inverses[f] @ (total_gram - grams[f]) @ inverses[f]
            else:
                shared = total_gram - grams[f] - grams[g]
                w[rows, cols] = inverses[f] @ shared @ inverses[g] - inverses[f] - inverses[g]
    m = np.hstack([w[:, g * p : (g + 1) * p] @ grams[g] for g in range(k)])
    m2 = m @ m
    t1, t2, t3 = float(np.trace(m)), float(np.trace(m2)), float(np.sum(m2 * m.T))
    return (
        numbers + t1,
        2.0 * (numbers + 2.0 * t1 + t2),
        8.0 * (numbers + 3.0 * t1 + 3.0 * t2 + t3),
    )


def time_folds(order, poses, n_folds: int) -> np.ndarray:
    """(n,) fold of each point: K blocks contiguous in time, each of whole poses. order (n,): when
    each row was measured (s, or the table row where the campaign has no time column: the row
    order is then taken as the measurement order); poses (n,) labels. The poses, in the order of
    their first row, are cut into K runs of about n / K rows, so the held-out block is measured
    after (or before) everything the fit keeps but for the blocks on its other side: prediction in
    time rather than interpolation among poses measured minutes apart."""
    order, poses = np.asarray(order, dtype=float), np.asarray(poses)
    labels, inverse = np.unique(poses, return_inverse=True)
    if len(labels) < n_folds:
        raise ValueError(f"{len(labels)} poses cannot make {n_folds} time blocks of whole poses")
    first = np.full(len(labels), np.inf)
    np.minimum.at(first, inverse.ravel(), order)
    sequence = np.argsort(first, kind="stable")
    counts = np.bincount(inverse.ravel(), minlength=len(labels))[sequence]
    # a pose goes to the block its middle row falls in; poses of very unequal sizes that would
    # leave a block empty are cut by count instead
    middle = np.cumsum(counts) - counts / 2.0
    block = np.minimum((middle * n_folds / counts.sum()).astype(int), n_folds - 1)
    if len(np.unique(block)) < n_folds:
        block = np.arange(len(labels)) * n_folds // len(labels)
    fold_of = np.empty(len(labels), dtype=int)
    fold_of[sequence] = block
    return fold_of[inverse.ravel()]


# k-means restarts of `region_folds`: Lloyd's iterations find a local optimum, the best of a few
# k-means++ starts is stable against an unlucky one
REGION_STARTS = 8
REGION_ITERATIONS = 100


def region_folds(features, poses, n_folds: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(n,) fold of each point and (K, d) the regions' centres: whole poses clustered by k-means on
    their mean features (n, d) into K regions, each region a fold. A region is a Voronoi cell of
    the features (every pose is nearer its own centre than any other), so a held-out fold is a
    contiguous part of the measured domain and its fit predicts it from around it: extrapolation,
    where folds of poses in turn interpolate. Deterministic: k-means++ starts drawn from a numpy
    Generator seeded by `seed`, the start of least within-region sum of squares kept; folds
    numbered by their first pose label."""
    features, poses = np.asarray(features, dtype=float), np.asarray(poses)
    labels, inverse = np.unique(poses, return_inverse=True)
    inverse = inverse.ravel()
    if len(labels) < n_folds:
        raise ValueError(f"{len(labels)} poses cannot make {n_folds} regions of whole poses")
    counts = np.bincount(inverse, minlength=len(labels))
    points = np.zeros((len(labels), features.shape[1]))
    np.add.at(points, inverse, features)
    points /= counts[:, None]
    rng = np.random.default_rng(seed)
    best, best_cost = None, np.inf
    for _ in range(REGION_STARTS):
        centres = _kmeans_plus_plus(points, n_folds, rng)
        for _ in range(REGION_ITERATIONS):
            assigned = np.argmin(_squared_distances(points, centres), axis=1)
            moved = np.array(
                [points[assigned == k].mean(axis=0) if np.any(assigned == k) else centres[k] for k in range(n_folds)]
            )
            if np.allclose(moved, centres, rtol=0.0, atol=1e-12):
                break
            centres = moved
        assigned = np.argmin(_squared_distances(points, centres), axis=1)
        cost = float(np.sum((points - centres[assigned]) ** 2))
        if len(np.unique(assigned)) == n_folds and cost < best_cost - 1e-12:
            best, best_cost = (assigned, centres), cost
    if best is None:  # as many distinct poses as regions at most: one region each
        raise ValueError(f"the poses' features do not make {n_folds} distinct regions")
    assigned, centres = best
    order = np.argsort([np.flatnonzero(assigned == k)[0] for k in range(n_folds)])
    renumber = np.empty(n_folds, dtype=int)
    renumber[order] = np.arange(n_folds)
    return renumber[assigned][inverse], centres[order]


def _squared_distances(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(m, K) squared distances of points (m, d) to centres (K, d)."""
    return np.sum((points[:, None, :] - centres[None, :, :]) ** 2, axis=-1)


def _kmeans_plus_plus(points: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k starting centres (k, d) by k-means++: each next one drawn with probability proportional
    to the squared distance to the nearest already drawn."""
    centres = [points[rng.integers(len(points))]]
    for _ in range(1, k):
        nearest = np.min(_squared_distances(points, np.array(centres)), axis=1)
        total = nearest.sum()
        index = rng.choice(len(points), p=nearest / total) if total > 0 else rng.integers(len(points))
        centres.append(points[index])
    return np.array(centres)


def t_threshold(normal_standard_errors: float, n_folds: int) -> float:
    """The fall (in standard errors over n_folds folds) a candidate needs: the one-sided level of
    `normal_standard_errors` under a normal law, 1 - Phi(z), held at Student's t with K - 1 degrees
    of freedom (the standard error is estimated from K paired differences). K = 5 at z = 2
    (level 2.3 %): 2.87."""
    import scipy.stats

    if n_folds < 2:
        return math.inf
    return float(scipy.stats.t.isf(scipy.stats.norm.sf(normal_standard_errors), n_folds - 1))


def cv_gain(current: CrossValidation, candidate: CrossValidation) -> dict:
    """Paired comparison over the same folds: the fall of the held-out mean squared residual (its
    mean over folds and its standard error, mm^2), both pooled RMSEs (mm), each fold's relative
    fall 1 - after / before, and the decision's statistic `cv_mse_fall_in_se`: the mean over folds
    of log(before / after) over its standard error. On the log scale a fold whose error was large
    before weighs as much as the others, no more: a candidate that removes most of the error in
    every fold is not held back because one fold had more error to remove (the differences' spread
    would then be that fold's), and one fold whose fit departs cannot outweigh the rest."""
    kept = current.kept & candidate.kept  # a fold that departed in either fit decides nothing
    before, after = current.mse[kept], candidate.mse[kept]
    difference = before - after
    k = len(difference)
    standard_error = float(np.std(difference, ddof=1) / math.sqrt(k)) if k > 1 else math.inf
    mean = float(np.mean(difference)) if k else math.nan
    tiny = np.finfo(float).tiny
    log_fall = np.log(np.maximum(before, tiny)) - np.log(np.maximum(after, tiny))
    log_se = float(np.std(log_fall, ddof=1) / math.sqrt(k)) if k > 1 else math.inf
    log_mean = float(np.mean(log_fall)) if k else math.nan
    return {
        "cv_rmse_before_mm": current.rmse * 1e3,
        "cv_rmse_mm": candidate.rmse * 1e3,
        "cv_gain": 1.0 - candidate.rmse / current.rmse,
        "cv_mse_fall_mm2": mean * 1e6,
        "cv_mse_fall_se_mm2": standard_error * 1e6,
        "cv_fold_falls": (1.0 - candidate.mse / np.maximum(current.mse, tiny)).tolist(),
        # fewer than two folds kept: no decision (a candidate cannot pass on one fold)
        "cv_mse_fall_in_se": -math.inf
        if k < 2
        else (log_mean / log_se if log_se > 0 else (math.inf if log_mean > 0 else -math.inf)),
        "cv_departed_folds": np.flatnonzero(~kept).tolist(),
        "cv_folds": k,
        "cv_noise_inflation_before": current.noise_inflation,
        "cv_noise_inflation": candidate.noise_inflation,
        # what the closure test holds each to (`remaster.loop.noise_floor.verdict`)
        "cv_held_out_numbers_before": current.held_out_numbers,
        "cv_held_out_numbers": candidate.held_out_numbers,
        "cv_null_cumulants_before": None if current.null_cumulants is None else list(current.null_cumulants),
        "cv_null_cumulants": None if candidate.null_cumulants is None else list(candidate.null_cumulants),
    }
