"""The residual Gaussian process over the joints as a candidate of the selection: fitted and
cross-validated on a fit's residuals in the robot frame (`gp_candidate`), and scored by the
parametric candidates' rule (`score_gp`).
"""

from __future__ import annotations

import numpy as np

from ..inference import evidence
from ..inference.gp import loop_candidate
from ..inference.gp.evidence_gain import EXACT_ROWS
from ..inference.readings import Readings
from ..units import MM
from .fitted import Fitted
from .held_out import TimeBlocked
from .scoring import Signature, judged
from .settings import LoopSettings


def gp_candidate(
    current: Fitted, data: Readings, rotation: np.ndarray, folds: np.ndarray, settings: LoopSettings
) -> loop_candidate.Candidate:
    """The Gaussian process fitted and cross-validated on a fit's residuals in the robot frame
    (rotation (3, 3) its registration, robot -> sensor)."""
    return loop_candidate.fit_and_score(
        data.q,
        current.residuals() @ rotation,
        current.cv.held_out @ rotation,
        folds,
        int(settings.residual_gp["subset"]),
        int(settings.residual_gp["inducing"]),
        int(settings.residual_gp.get("exact_rows", EXACT_ROWS)),
    )


def score_gp(
    current: Fitted,
    data: Readings,
    rotation: np.ndarray,
    folds: np.ndarray,
    settings: LoopSettings,
    in_time: TimeBlocked | None = None,
) -> tuple[loop_candidate.Candidate, dict]:
    """The Gaussian process on the current fit's residuals (robot frame) and its scores by the
    parametric candidates' rule: evidence gain (`remaster.inference.gp.evidence_gain`: exact or Titsias,
    hyperparameters integrated, against iid noise with sigma integrated alike), pose-grouped
    cross-validated fall, and its fall over the time blocks (`TimeBlocked.gp_gain`)."""
    residual = current.residuals()
    gp = gp_candidate(current, data, rotation, folds, settings)
    signature = Signature(residual, gp.gp.mean(data.q) @ rotation.T)
    scores = {
        "log_evidence_gain": gp.log_evidence_gain,
        **evidence.cv_gain(current.cv, evidence.CrossValidation(gp.mse, gp.points)),
        "sigma_mm": gp.gp.hyper.noise_std / MM,
        "parameters": ["lengthscales", "signal_std", "noise_std"],
        "explained_fraction": signature.explained,
        "evidence": gp.evidence.report(),
    }
    if in_time is not None:
        scores.update({f"time_blocked_{k}": v for k, v in in_time.gp_gain(current, data, rotation, settings).items()})
    return gp, judged(scores, settings)
