"""A candidate's scores against the current fit and the rule it passes by (`score`, `passes`): its
evidence gain, its pose-grouped cross-validated fall, its falls over the time blocks and the
held-out regions, its signature (what it would explain) and whether its own parameters stay
within their priors.

SI inside (m, rad); the JSON-ready scores are in mm where their names say so.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..inference import evidence
from ..units import MM
from .fitted import Fitted
from .held_out import Regions, cv_threshold
from .settings import LoopSettings

# --------------------------------------------------------------------------- diagnose and decide


@dataclass(frozen=True, eq=False)
class Signature:
    """What a candidate would explain: residual (n, 3) m of the current fit on the optimization
    set, effect (n, 3) m the change in the prediction the candidate's fit makes; when the
    candidate is the missing effect, effect ~ residual. residual - effect is the candidate's
    residual, so `explained` is the fraction of the sum of squares it removes."""

    residual: np.ndarray
    effect: np.ndarray

    @property
    def explained(self) -> float:
        """1 - |residual - effect|^2 / |residual|^2."""
        return float(1.0 - np.sum((self.residual - self.effect) ** 2) / np.sum(self.residual**2))


def time_blocked_gain(current: evidence.CrossValidation, candidate: evidence.CrossValidation) -> dict:
    """The candidate's paired fall over the time blocks (`evidence.cv_gain`), keys prefixed time_blocked_."""
    return {f"time_blocked_{k}": v for k, v in evidence.cv_gain(current, candidate).items()}


def beyond_prior(current: Fitted, candidate: Fitted) -> dict:
    """The candidate's own parameter (of the blocks `current` lacks) farthest from 0 in its prior
    standard deviations at the candidate's mode: {'parameter', 'prior_stds'} (0 and '' for blocks
    without priors). Far beyond its prior (`evidence.PRIOR_RANGE`) an estimate is not that effect's:
    the effect imitates something else the data hold."""
    model = candidate.model
    own = np.array([model.block_of[n] not in current.model.blocks for n in model.names], bool)
    finite = own & np.isfinite(model.prior_std) & (model.prior_std > 0)
    if not finite.any():
        return {"parameter": "", "prior_stds": 0.0}
    ratio = np.where(finite, np.abs(candidate.theta) / np.where(finite, model.prior_std, 1.0), 0.0)
    worst = int(np.argmax(ratio))
    return {"parameter": model.names[worst], "prior_stds": float(ratio[worst])}


def region_gain(current: Fitted, candidate: Fitted, regions: Regions) -> dict:
    """The candidate's paired change over the held-out regions (`Regions`), keys prefixed region_:
    per fold set ('joint_space', 'tool_axis') each region's relative fall 1 - after / before of its
    held-out mean square and whether either fit departed there; over every region of every set the
    median of log(before / after) (`region_median_log_fall`, the decision's statistic: > 0 when most
    regions are predicted better), how many regions improved, and the worst region with its fall.
    A departed region's fit is its own mode (`evidence.cross_validate`): there its error is what
    the effect does where it did not see, so it counts like the others, one vote of the median."""
    tiny = np.finfo(float).tiny
    per_set, log_falls, where = {}, [], []
    for name, folds in regions.folds.items():
        before, after = current.cross_validated(folds), candidate.cross_validated(folds)
        falls = 1.0 - after.mse / np.maximum(before.mse, tiny)
        per_set[name] = {
            "fold_falls": falls.tolist(),
            "held_out_points": after.points.tolist(),
            "departed": np.flatnonzero(~(before.kept & after.kept)).tolist(),
            "cv_rmse_before_mm": before.rmse / MM,
            "cv_rmse_mm": after.rmse / MM,
        }
        log_falls += (np.log(np.maximum(before.mse, tiny)) - np.log(np.maximum(after.mse, tiny))).tolist()
        where += [(name, k, float(f)) for k, f in enumerate(falls)]
    worst = min(where, key=lambda w: w[2])
    return {
        "region_folds": per_set,
        "region_median_log_fall": float(np.median(log_falls)),
        "region_folds_improved": int(np.sum(np.array(log_falls) > 0)),
        "region_folds_total": len(log_falls),
        "region_worst": {"set": worst[0], "fold": worst[1], "fall": worst[2]},
    }


def score(
    current: Fitted,
    candidate: Fitted,
    settings: LoopSettings,
    blocked: np.ndarray | None = None,
    regions: Regions | None = None,
) -> dict:
    """A candidate's scores against the current fit (JSON-ready), and whether it passes; blocked
    (n,): the time blocks (`TimeBlocked`) a candidate must also not lose on, None without them;
    regions: the held-out regions (`Regions`) whose majority it must predict better, None without."""
    out = {
        "log_evidence_gain": candidate.mode.log_evidence - current.mode.log_evidence,
        "bic_gain": current.mode.bic() - candidate.mode.bic(),
        **evidence.cv_gain(current.cv, candidate.cv),
        **(
            {}
            if blocked is None
            else time_blocked_gain(current.cross_validated(blocked), candidate.cross_validated(blocked))
        ),
        "sigma_mm": candidate.mode.sigma / MM,
        "parameters": list(candidate.reduction.kept),
        "dropped": dict(candidate.reduction.dropped),
        "weak": dict(candidate.reduction.weak),
        "condition_number": candidate.reduction.condition_number,
        **({} if regions is None else region_gain(current, candidate, regions)),
        "beyond_prior": beyond_prior(current, candidate),
    }
    return judged(out, settings)


def shortfalls(scores: Mapping, settings: LoopSettings) -> list[str]:
    """Which of the selection's criteria a candidate's scores miss, each with its numbers (`passes`):
    empty when it passes."""
    out = []
    gain, needed = scores["log_evidence_gain"], settings.min_log_evidence_gain
    if not gain > needed:
        out.append(f"evidence gain {gain:.3g} nats, not above {needed:g}")
    fall, threshold = scores["cv_mse_fall_in_se"], cv_threshold(settings, scores.get("cv_folds"))
    if not fall > threshold:
        out.append(f"cross-validated fall {fall:.3g} SE, not above {threshold:.3g}")
    blocked = scores.get("time_blocked_cv_mse_fall_mm2")
    if blocked is not None and not blocked > 0:
        out.append("no fall over the time blocks (it does not predict a stretch of the campaign it did not see)")
    median = scores.get("region_median_log_fall")
    if median is not None and not median > 0:
        out.append(
            f"most held-out regions not predicted better ({scores['region_folds_improved']} of "
            f"{scores['region_folds_total']}, median fall {100 * -math.expm1(-median):.2g} %): it does not "
            "carry over to a part of the domain it did not see"
        )
    far = scores.get("beyond_prior") or {}
    if far.get("prior_stds", 0.0) > evidence.PRIOR_RANGE:
        out.append(symptom_text(far))
    return out


def symptom_text(far: Mapping) -> str:
    """Why an estimate far beyond its prior is not kept as its effect (`beyond_prior`)."""
    return (
        f"a symptom, not this effect: {far['parameter']} at {far['prior_stds']:.3g} prior std (beyond "
        f"{evidence.PRIOR_RANGE:g}, where its prior, the effect's physical range, puts 6e-7 of its mass): "
        "it absorbs something else the data hold"
    )


def passes(scores: Mapping, settings: LoopSettings) -> bool:
    """The selection's rule, for a parametric candidate and the residual GP alike: the evidence gain
    exceeds min_log_evidence_gain AND the pose-grouped cross-validated fall exceeds `cv_threshold`
    standard errors AND, where the campaign has time blocks, the fall over blocks contiguous in time
    is positive: the effect also predicts poses it did not interpolate between (folds of whole poses
    assigned in turn are each a thinned copy of the same design) AND, where the campaign has held-out
    regions (`Regions`), the median of their log falls is positive: most regions of the joint space
    and of the tool's orientation are predicted better when left out: one region the effect
    extrapolates badly to is shown (`region_worst`) and is one vote, where a mean over its standard
    error would let that one fold's spread veto the effect, AND no parameter of its own sits
    beyond `evidence.PRIOR_RANGE` prior std (`beyond_prior`): there it is a symptom of something else."""
    return not shortfalls(scores, settings)


def judged(scores: dict, settings: LoopSettings) -> dict:
    """scores with `passed` (`passes`) and `why_not` (`shortfalls`, '; '-joined; '' when it passes)."""
    missed = shortfalls(scores, settings)
    scores["passed"], scores["why_not"] = not missed, "; ".join(missed)
    return scores
