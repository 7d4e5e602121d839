"""The residual GP as a candidate of the loop closure: fitted on every row of the current model's
residuals, scored like a parametric candidate (evidence gain over independent noise, pose-grouped
cross-validation), and written with the loop's results and read back from them.

SI inside (m, rad).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .evidence_gain import EXACT_ROWS, GPEvidence, log_evidence_gain
from .kernels import Hyperparameters
from .likelihood import iid_log_likelihood
from .residual import INDUCING, SUBSET, ResidualGP, fit_hyperparameters, inducing_count, relevance


@dataclass(frozen=True, eq=False)
class Candidate:
    """The GP as a candidate of the loop: fitted on every row, its evidence gain over independent
    noise (nats; `evidence` says how it was obtained), and its pose-grouped cross-validation: mse
    (K,) m^2 per point of the held-out residuals less the GP's prediction from the other folds,
    points (K,)."""

    gp: ResidualGP
    q: np.ndarray
    residuals: np.ndarray
    log_evidence_gain: float
    mse: np.ndarray
    points: np.ndarray
    evidence: GPEvidence | None = None

    def relevance(self) -> np.ndarray:
        return relevance(self.gp.hyper, self.q)


def fit_and_score(
    q, residuals, held_out, folds, subset: int = SUBSET, inducing: int = INDUCING, exact_rows: int = EXACT_ROWS
) -> Candidate:
    """Fit and score the GP on readings q (n, N) rad and residuals (n, 3) m of the current model;
    held_out (n, 3) m: each row's residual under the current model fitted without its fold, folds
    (n,) the pose-grouped folds; inducing: the fewest inducing inputs, more where the fitted
    hyperparameters need them (`residual.inducing_count`).

    Evidence (`evidence_gain`): the GP's marginal likelihood, exact up to exact_rows rows and
    Titsias' bound above, with its hyperparameters integrated by a Laplace step in their logs,
    against independent noise with sigma integrated the same way; the parametric parameters stay at
    the current mode in both. Cross-validation: for each fold the GP's hyperparameters are refitted
    on the other folds (from the whole set's, which saves most of the cost) and it is conditioned
    on their residuals; its mean is subtracted from the fold's held-out residuals. Hyperparameters
    fitted with the held-out rows would tune their lengthscales to the very noise they then predict
    (a few per cent of spurious gain on pure noise)."""
    q, residuals, held_out = (np.asarray(a, dtype=float) for a in (q, residuals, held_out))
    hyper = fit_hyperparameters(q, residuals, subset)
    inducing = inducing_count(q, hyper, inducing)  # the folds' GPs and the evidence's bound through as many
    gp = ResidualGP(q, residuals, hyper, inducing)
    price = 0.5 * (int(hyper.turned.sum()) + 1) * math.log(residuals.size)
    dtc_gain = gp.log_likelihood - iid_log_likelihood(residuals) - price  # the former measure, for comparison
    scored = log_evidence_gain(q, residuals, hyper, exact_rows, inducing, subset)
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
