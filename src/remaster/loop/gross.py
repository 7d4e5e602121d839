"""Gross errors after modelling: every row of both sets screened with the loop closure's final model.

The prepare stage's screen (`remaster.inference.fit.flag_outliers`) judges the rows by the paper's
zero-offset model. Where that model lacks an effect its residuals are not noise, so it flags good
rows and can miss a glitch of a few mm; its rows are therefore only provisional. Here each row is
judged by the model the loop closure chose, at the same family-wise level `outliers/alpha`:

- the residual e_i (3,) of row i at the final model's mode, whitened by its noise model (a laser
  tracker's range/transverse noise when chosen, `remaster.noise`), is compared with its covariance
  under that model: s^2 (I - H_i) for a row the model was fitted on, s^2 (I + H_i) for a row it was
  not (the rows it left out, every validation row: a prediction), H_i = J_i Sigma J_i^T / sigma^2
  the row's (3, 3) leverage, J_i its whitened Jacobian and Sigma the Laplace covariance of the
  parameters. s^2 = SS / (3 n - tr H), the whitened sum of squares over the residual degrees of
  freedom (the mode's own sigma is short of the noise by the share the parameters absorb);
- d_i^2 = e_i^T C_i^-1 e_i. For a linear Gaussian model d^2 / dof of a fitted row is
  Beta(3/2, (dof - 3) / 2) (internally studentized) and d^2 / 3 of a new row is F(3, dof)
  (externally studentized), dof = 3 n - tr H. Row i is beyond the threshold when d_i^2 exceeds that
  law's quantile at 1 - alpha / n_set: Bonferroni over the n_set measured rows of its set, so a
  clean set has at most probability alpha of any row beyond it;
- with the residual Gaussian process added, e_i is the residual after the GP's mean (not whitened)
  and C_i = s_cv^2 I for a fitted row, (s_cv^2 + v_i) I for another, s_cv the GP's pose-grouped
  cross-validated RMS per axis (what it leaves at poses it was not fitted on, at least its noise
  std) and v_i its posterior variance at the row, against chi2_3.

A row beyond the threshold is a gross error only when it is isolated: (1) not every measured
configuration of its pose is beyond it (an error shared by a pose's configurations is where the
marker was, not a glitch of one reading), and (2) its set has at most max(1, max_share n_set) rows
beyond it. More than that is a systematic departure (a moved sensor, a distortion, an effect the
model lacks): no row of the set is then a gross error, and the acceptance test judges the set.

The optimization set is screened in turns (`remaster.loop.loop_closure.close_loop`): the loop is
fitted without the current set of gross errors (first the provisional one), every optimization row
is screened, and when the screen finds another set the loop is fitted again without it, until the
set it finds is the one it was fitted without (at most MAX_ROUNDS fits). The validation set is
screened once, with the final model and the optimization registration; it never enters a fit.

SI inside (m); the report's numbers are in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from ..inference.identifiability import JACOBIAN_STEP
from ..inference.readings import Readings
from ..units import MM

MAX_ROUNDS = 4  # fits of the loop in the optimization set's screen: the first and at most three refits
ISOLATED = (
    "a row beyond the threshold is a gross error only when not every measured configuration of its pose is "
    "beyond it, and its set has at most max(1, max_share x its rows) rows beyond it; more is a systematic "
    "departure (left to the acceptance test), not gross errors"
)
METHOD = (
    "the loop closure's final model at its mode: residual whitened by its noise model, standardized by its "
    "covariance s^2 (I - H_i) for fitted rows (Beta law) and s^2 (I + H_i) for rows not fitted (F law), "
    "s^2 the whitened sum of squares over 3n - tr H; with the residual GP added, the residual after its mean "
    "against chi2_3 at the GP's cross-validated RMS per axis (plus its posterior variance for rows not fitted); Bonferroni over each set's measured rows"
)


@dataclass(frozen=True, eq=False)
class Screen:
    """One set's rows judged by the final model. rows, poses (n,) table rows and pose labels of the
    set's measured rows; fitted (n,) whether the model was fitted on the row; error (n,) m the
    residual's length (not whitened); distance2 (n,) d_i^2; threshold2 (n,) its threshold; alpha and
    max_share as judged."""

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


def beta_quantile(a: float, b: float, upper: float) -> float:
    """x with P(Beta(a, b) > x) = upper."""
    import scipy.special

    return float(scipy.special.betainccinv(a, b, upper))


def thresholds(alpha: float, n_set: int, dof: float) -> tuple[float, float]:
    """(fitted, not fitted) thresholds of d^2 at family-wise level alpha over n_set rows with dof
    residual degrees of freedom (module docstring: Beta and F laws)."""
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


def _leverage(model, theta, covariance) -> np.ndarray:
    """(n, 3, 3) J_i Sigma J_i^T of the model's rows, J_i their (3, P) whitened Jacobian at theta."""
    jacobian = model.weighted_jacobian(theta, JACOBIAN_STEP).reshape(model.n_points, 3, -1)
    return np.einsum("nip,pq,njq->nij", jacobian, covariance, jacobian)


def screen(selection, fitted: Readings, data: Readings, poses, set_name: str, alpha: float, max_share: float) -> Screen:
    """Judge every row of `data` (a set's measured rows, poses (n,)) by the selection's final model
    (`remaster.loop.selection.Selection`), fitted on `fitted` (module docstring)."""
    if len(data.rows) == 0:
        nothing = np.empty(0)
        return Screen(
            set_name,
            data.rows,
            np.asarray(poses),
            nothing.astype(bool),
            nothing,
            nothing,
            nothing,
            alpha,
            max_share,
            math.nan,
            "",
        )
    final = selection.final
    mode = final.mode
    model = final.model.on(data)
    is_fitted = np.isin(data.rows, fitted.rows)
    covariance = mode.covariance[:-1, :-1]
    n = len(data.rows)
    if selection.gp_added:
        # the GP's noise is what it leaves where it was fitted; at new poses it leaves more, which
        # its pose-grouped cross-validation measures: that scale, per axis, for every row
        candidate = selection.gp
        held_out = float(np.sum(candidate.mse * candidate.points) / np.sum(candidate.points)) / 3.0
        scale = math.sqrt(max(held_out, candidate.gp.hyper.noise_std**2))
        e = data.measured - selection.prediction(data)
        # a row it was not fitted on: plus the GP's own posterior variance there (far from its rows)
        variance = scale**2 + np.where(is_fitted, 0.0, candidate.gp.variance(data.q))
        return Screen(
            set_name,
            data.rows,
            np.asarray(poses),
            is_fitted,
            np.linalg.norm(e, axis=1),
            np.sum(e**2, axis=1) / variance,
            np.full(n, chi2_threshold(alpha, n)),
            alpha,
            max_share,
            scale,
            "chi2_3 at the residual GP's cross-validated RMS per axis",
        )
    raw = model.residuals(final.theta)
    e = model.whitened(raw)
    leverage = (
        np.concatenate(
            [
                _leverage(final.model.on(data.subset(slice(begin, begin + LEVERAGE_ROWS))), final.theta, covariance)
                for begin in range(0, n, LEVERAGE_ROWS)
            ]
        )
        / mode.sigma**2
    )
    own = mode.jacobian.reshape(-1, 3, mode.jacobian.shape[1])
    used = float(np.einsum("nip,pq,niq->", own, covariance, own) / mode.sigma**2)  # tr H over the fitted rows
    dof = mode.n_residuals - used
    scale2 = mode.sum_squares / dof
    sign = np.where(is_fitted, -1.0, 1.0)[:, None, None]
    cov = scale2 * (np.eye(3) + sign * leverage)
    fitted_threshold, new_threshold = thresholds(alpha, n, dof)
    return Screen(
        set_name,
        data.rows,
        np.asarray(poses),
        is_fitted,
        np.linalg.norm(raw, axis=1),
        _quadratic(e, cov),
        np.where(is_fitted, fitted_threshold, new_threshold),
        alpha,
        max_share,
        math.sqrt(scale2),
        "Beta (fitted rows) / F (rows not fitted)",
    )
