"""Gross errors judged by a fitted model: the rule both screens apply, the zero-offset model's in the
prepare stage (`least_squares_screen`) and the loop closure's final model's (`remaster.loop.gross`).

- The residual e_i (3,) of row i at the model's fit, whitened by its noise model, is compared with
  its covariance under that model: s^2 (I - H_i) for a row the model was fitted on, s^2 (I + H_i)
  for a row it was not (a prediction), H_i = J_i Sigma J_i^T / sigma^2 the row's (3, 3) leverage,
  J_i its whitened Jacobian and Sigma the parameters' covariance. s^2 = SS / (3 n - tr H), the
  whitened sum of squares over the residual degrees of freedom (the fit's own sigma is short of the
  noise by the share the parameters absorb);
- d_i^2 = e_i^T C_i^-1 e_i. For a linear Gaussian model d^2 / dof of a fitted row is
  Beta(3/2, (dof - 3) / 2) (internally studentized) and d^2 / 3 of a new row is F(3, dof)
  (externally studentized), dof = 3 n - tr H. Row i is beyond the threshold when d_i^2 exceeds that
  law's quantile at 1 - alpha / n_set: Bonferroni over the n_set measured rows of its set, so a
  clean set has at most probability alpha of any row beyond it.

A row beyond the threshold is a gross error only when it is isolated (`ISOLATED`): where the model
lacks an effect, its error is shared by many rows or by a pose's every configuration, and the
acceptance test judges it, not this screen.

The rows are found in turns (`settle`): fitted without the current set (first the robust screen's,
`remaster.inference.fit.flag_outliers`), every row screened, refitted without the rows found, until
they are the rows it was fitted without (at most MAX_ROUNDS fits; a cycle stops it).

SI inside (m); the report's numbers are in mm.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from ..units import MM
from .identifiability import JACOBIAN_STEP

MAX_ROUNDS = 4  # fits in a screen's turns: the first and at most three refits
ISOLATED = (
    "a row beyond the threshold is a gross error only when not every measured configuration of its pose is "
    "beyond it, and its set has at most max(1, max_share x its rows) rows beyond it; more is a systematic "
    "departure (left to the acceptance test), not gross errors"
)
STUDENTIZED = "Beta (fitted rows) / F (rows not fitted)"
LEAST_SQUARES_METHOD = (
    "the zero-offset model's least-squares fit: residual standardized by s^2 (I - H_i) for fitted rows (Beta law) "
    "and s^2 (I + H_i) for rows not fitted (F law), s^2 the sum of squares over 3n - P; Bonferroni over the "
    "optimization set's measured rows"
)


@dataclass(frozen=True, eq=False)
class Screen:
    """One set's rows judged by a fitted model. rows, poses (n,) table rows and pose labels of the
    set's measured rows; fitted (n,) whether the model was fitted on the row; error (n,) m the
    residual's length (not whitened); distance2 (n,) d_i^2; threshold2 (n,) its threshold; alpha and
    max_share as judged; scale (m) the noise std the distances are in; law: the threshold's law."""

    set_name: str
    rows: np.ndarray
    poses: np.ndarray
    fitted: np.ndarray
    error: np.ndarray
    distance2: np.ndarray
    threshold2: np.ndarray
    alpha: float
    max_share: float
    scale: float
    law: str

    @classmethod
    def pending(cls, set_name: str, rows, poses, fitted, error, alpha: float, max_share: float) -> Screen:
        """The set's rows before they are judged: distances and thresholds still empty."""
        nothing = np.empty(0)
        return cls(set_name, rows, np.asarray(poses), fitted, error, nothing, nothing, alpha, max_share, math.nan, "")

    @property
    def beyond(self) -> np.ndarray:
        """(n,) rows beyond the threshold."""
        return self.distance2 > self.threshold2

    @property
    def limit(self) -> int:
        """The most rows beyond the threshold that can still be isolated gross errors."""
        return max(1, int(math.floor(self.max_share * len(self.rows))))

    @property
    def systematic(self) -> bool:
        return int(self.beyond.sum()) > self.limit

    @property
    def isolated(self) -> np.ndarray:
        """(n,) rows beyond the threshold whose pose has a measured configuration that is not."""
        beyond = self.beyond
        if not beyond.any():
            return beyond.copy()
        _, pose_of = np.unique(self.poses, return_inverse=True)
        rows, rows_beyond = np.bincount(pose_of), np.bincount(pose_of, weights=beyond)
        shared = (rows > 1) & (rows_beyond == rows)  # every configuration of the pose beyond it
        return beyond & ~shared[pose_of]

    @property
    def gross(self) -> np.ndarray:
        """Table rows judged gross errors, sorted (none when the set departs systematically)."""
        return np.sort(self.rows[self.isolated]) if not self.systematic else np.empty(0, dtype=int)

    def report(self) -> dict:
        """JSON-ready: the rows tested, the thresholds (as distances), the rows beyond them with their
        error and distance, which of them are gross errors, and why the others are not."""
        beyond, isolated = self.beyond, self.isolated
        gross = set(self.gross.tolist())
        listed = []
        for k in np.flatnonzero(beyond):
            row = int(self.rows[k])
            why = (
                "gross error"
                if row in gross
                else "systematic: too many rows beyond the threshold"
                if self.systematic
                else "not isolated: every configuration of its pose is beyond the threshold"
                if not isolated[k]
                else ""
            )
            listed.append(
                {
                    "row": row,
                    "pose": self.poses[k].item() if hasattr(self.poses[k], "item") else self.poses[k],
                    "fitted": bool(self.fitted[k]),
                    "error_mm": float(self.error[k] / MM),
                    "distance": float(math.sqrt(self.distance2[k])),
                    "threshold": float(math.sqrt(self.threshold2[k])),
                    "judged": why,
                }
            )
        thresholds = {
            kind: float(math.sqrt(self.threshold2[mask][0])) if mask.any() else None
            for kind, mask in (("fitted_rows", self.fitted), ("rows_not_fitted", ~self.fitted))
        }
        return {
            "rows_tested": int(len(self.rows)),
            "law": self.law,
            "scale_mm": self.scale / MM,
            "threshold_distance": thresholds,
            "threshold_mm_at_scale": {k: None if v is None else v * self.scale / MM for k, v in thresholds.items()},
            "beyond_threshold": listed,
            "most_isolated": self.limit,
            "systematic": self.systematic,
        }


def empty_screen(set_name: str, rows, poses, alpha: float, max_share: float) -> Screen:
    """The screen of a set without measured rows."""
    return Screen.pending(set_name, rows, poses, np.empty(0, dtype=bool), np.empty(0), alpha, max_share)


def beta_quantile(a: float, b: float, upper: float) -> float:
    """x with P(Beta(a, b) > x) = upper."""
    import scipy.special

    return float(scipy.special.betainccinv(a, b, upper))


def thresholds(alpha: float, n_set: int, dof: float) -> tuple[float, float]:
    """(fitted, not fitted) thresholds of d^2 at family-wise level alpha over n_set rows with dof
    residual degrees of freedom (module docstring: Beta and F laws); infinite (nothing beyond them)
    with at most 3 degrees of freedom, where no row's residual is free of the fit."""
    if dof <= 3.0:
        return math.inf, math.inf
    upper = alpha / max(n_set, 1)
    fitted = dof * beta_quantile(1.5, (dof - 3.0) / 2.0, upper)
    b = beta_quantile(1.5, dof / 2.0, upper)  # 3 F / (3 F + dof) ~ Beta(3/2, dof/2)
    return fitted, dof * b / (1.0 - b)


def chi2_threshold(alpha: float, n_set: int) -> float:
    import scipy.special

    return float(scipy.special.chdtri(3, alpha / max(n_set, 1)))


def _quadratic(e: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """e_i^T C_i^-1 e_i (n,) of residuals (n, 3) and covariances (n, 3, 3); a covariance whose
    leverage leaves nothing (a row that alone determines a parameter) is floored, not inverted."""
    values, vectors = np.linalg.eigh(covariance)
    floor = 1e-6 * np.max(values, axis=1, keepdims=True)
    projected = np.einsum("nij,ni->nj", vectors, e)
    return np.sum(projected**2 / np.maximum(values, floor), axis=1)


# rows whose Jacobian is taken at once: its central differences hold (2 P, rows, 3) predictions
LEVERAGE_ROWS = 20_000


def leverage(model, theta, covariance) -> np.ndarray:
    """(n, 3, 3) J_i Sigma J_i^T of a block model's rows, J_i their (3, P) whitened Jacobian at
    theta, in chunks of LEVERAGE_ROWS rows."""

    def chunk(part):
        jacobian = part.weighted_jacobian(theta, JACOBIAN_STEP).reshape(part.n_points, 3, -1)
        return np.einsum("nip,pq,njq->nij", jacobian, covariance, jacobian)

    data = model.data
    return np.concatenate(
        [chunk(model.on(data.subset(slice(b, b + LEVERAGE_ROWS)))) for b in range(0, model.n_points, LEVERAGE_ROWS)]
    )


def studentized(judged: Screen, whitened: np.ndarray, hat: np.ndarray, sum_squares: float, dof: float) -> Screen:
    """`judged` (its rows, poses, fitted, error and level; distances left empty) with each row's
    distance and threshold by the Beta/F rule: whitened (n, 3) residuals, hat (n, 3, 3) the rows'
    leverages H_i, sum_squares the fit's whitened SS over dof residual degrees of freedom."""
    scale2 = sum_squares / dof if dof > 0 else math.nan
    sign = np.where(judged.fitted, -1.0, 1.0)[:, None, None]
    fitted_threshold, new_threshold = thresholds(judged.alpha, len(judged.rows), dof)
    return Screen(
        judged.set_name,
        judged.rows,
        judged.poses,
        judged.fitted,
        judged.error,
        _quadratic(whitened, scale2 * (np.eye(3) + sign * hat)) if dof > 3 else np.zeros(len(judged.rows)),
        np.where(judged.fitted, fitted_threshold, new_threshold),
        judged.alpha,
        judged.max_share,
        math.sqrt(scale2) if dof > 0 else math.nan,
        STUDENTIZED,
    )


def least_squares_screen(fitted_model, result, every, poses, alpha: float, max_share: float) -> Screen:
    """The rows of `every` (readings of a set's measured rows, poses (n,)) judged by a flat-prior
    least-squares fit (`least_squares.LaplaceResult`: covariance s^2 (J^T J)^-1) of `fitted_model`,
    a block model of points whose readings are some of them: H_i = J_i (J^T J)^-1 J_i^T, tr H = P."""
    if len(every.rows) == 0:
        return empty_screen("optimization", every.rows, poses, alpha, max_share)
    model = fitted_model.on(every)
    theta = result.theta_map
    is_fitted = np.isin(every.rows, fitted_model.data.rows)
    raw = model.residuals(theta)
    dof = result.n_residuals - len(theta)
    sum_squares = 2.0 * result.cost
    s2 = sum_squares / dof if dof > 0 else math.nan
    hat = leverage(model, theta, result.covariance) / s2 if dof > 0 else np.zeros((len(every.rows), 3, 3))
    judged = Screen.pending("optimization", every.rows, poses, is_fitted, np.linalg.norm(raw, axis=1), alpha, max_share)
    return studentized(judged, model.whitened(raw), hat, sum_squares, dof)


@dataclass(frozen=True, eq=False)
class Settled:
    """A screen's turns: the last fit (whatever `fit_and_screen` returned), the rows it was fitted
    without, the turns ([{fitted_without, found}]), and whether the rows found were those."""

    fit: Any
    excluded: np.ndarray
    history: list[dict]
    settled: bool

    def report(self) -> dict:
        return {"rounds": self.history, "settled": self.settled}


def settle(fit_and_screen: Callable[[np.ndarray], tuple[Any, np.ndarray]], provisional) -> Settled:
    """Fit without `provisional` (table rows), screen, and fit again without the rows found until
    they are the rows the fit left out (at most MAX_ROUNDS fits; a cycle stops it, and the last fit
    stands). fit_and_screen(excluded rows) -> (the fit, the table rows its screen finds)."""
    excluded, history = np.sort(np.asarray(provisional, dtype=int)), []
    for round_ in range(MAX_ROUNDS):
        fit, found = fit_and_screen(excluded)
        history.append({"fitted_without": excluded.tolist(), "found": found.tolist()})
        if np.array_equal(found, excluded):
            return Settled(fit, excluded, history, True)
        if any(np.array_equal(found, np.asarray(h["fitted_without"], dtype=int)) for h in history):
            break  # the screen turns in a cycle: the last fit stands, and the report says so
        if round_ == MAX_ROUNDS - 1:
            break  # no refit is left: the rows flagged stay the ones the last fit was fitted without
        excluded = found
    return Settled(fit, excluded, history, False)
