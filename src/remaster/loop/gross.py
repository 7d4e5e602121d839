"""Gross errors after modelling: every row of both sets screened with the loop closure's final model.

The prepare stage's screen (`remaster.inference.fit.screened_rows`) judges the rows by the paper's
zero-offset model. Where that model lacks an effect its residuals are not noise, so it can flag good
rows and miss a glitch of a few mm; its rows are therefore only where this screen starts. Here each row is
judged by the model the loop closure chose, at the same family-wise level `outliers/alpha`:

- the residual e_i (3,) of row i at the final model's mode, whitened by its noise model (a laser
  tracker's range/transverse noise when chosen, `remaster.noise`), is compared with its covariance
  under that model: s^2 (I - H_i) for a row the model was fitted on, s^2 (I + H_i) for a row it was
  not (the rows it left out, every validation row: a prediction), H_i = J_i Sigma J_i^T / sigma^2
  the row's (3, 3) leverage, J_i its whitened Jacobian and Sigma the Laplace covariance of the
  parameters. s^2 = SS / (3 n - tr H), the whitened sum of squares over the residual degrees of
  freedom (the mode's own sigma is short of the noise by the share the parameters absorb);
- d_i^2 = e_i^T C_i^-1 e_i against the Beta (fitted rows) and F (rows not fitted) laws' quantiles
  at 1 - alpha / n_set (`remaster.inference.gross_errors`, the rule the zero-offset model's screen
  in the prepare stage applies too);
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
fitted without the current set of gross errors (first the zero-offset model's), every optimization row
is screened, and when the screen finds another set the loop is fitted again without it, until the
set it finds is the one it was fitted without (`gross_errors.settle`). The validation set is
screened once, with the final model and the optimization registration; it never enters a fit.

SI inside (m); the report's numbers are in mm.
"""

from __future__ import annotations

import math

import numpy as np

from ..inference.gross_errors import Screen, chi2_threshold, empty_screen, leverage, studentized
from ..inference.readings import Readings

METHOD = (
    "the loop closure's final model at its mode: residual whitened by its noise model, standardized by its "
    "covariance s^2 (I - H_i) for fitted rows (Beta law) and s^2 (I + H_i) for rows not fitted (F law), "
    "s^2 the whitened sum of squares over 3n - tr H; with the residual GP added, the residual after its mean "
    "against chi2_3 at the GP's cross-validated RMS per axis (plus its posterior variance for rows not fitted); Bonferroni over each set's measured rows"
)


def screen(selection, fitted: Readings, data: Readings, poses, set_name: str, alpha: float, max_share: float) -> Screen:
    """Judge every row of `data` (a set's measured rows, poses (n,)) by the selection's final model
    (`remaster.loop.selection.Selection`), fitted on `fitted` (module docstring)."""
    if len(data.rows) == 0:
        return empty_screen(set_name, data.rows, poses, alpha, max_share)
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
    hat = leverage(model, final.theta, covariance) / mode.sigma**2
    own = mode.jacobian.reshape(-1, 3, mode.jacobian.shape[1])
    used = float(np.einsum("nip,pq,niq->", own, covariance, own) / mode.sigma**2)  # tr H over the fitted rows
    judged = Screen.pending(set_name, data.rows, poses, is_fitted, np.linalg.norm(raw, axis=1), alpha, max_share)
    return studentized(judged, model.whitened(raw), hat, mode.sum_squares, mode.n_residuals - used)
