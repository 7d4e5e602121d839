"""Diagnose and decide (`remaster.loop.loop_closure`, steps 1 and 2): every candidate effect fitted at
its posterior mode on the optimization set, scored by its evidence gain, its pose-grouped
cross-validation, its cross-validation over blocks contiguous in time and over held-out regions of
the domain (`TimeBlocked`, `Regions`) and its signature, and added greedily while one passes; a backward pass; the
residual Gaussian process over the joints, and with it added the parametric blocks scored again
with the GP present; last a laser tracker's range/transverse noise, for what the residual model leaves.

SI inside (m, rad); the JSON-ready scores are in mm where their names say so.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np  # scipy is imported in the functions that use it (test_architecture: light readers)

from .. import noise
from ..inference import blocks, evidence, metrics
from ..inference.blocks import BlockModel, Readings, Reduction
from ..inference.gp import loop_candidate, with_parameters
from ..inference.gp.evidence_gain import EXACT_ROWS
from ..inference.gp.kernels import Hyperparameters
from ..inference.gp.residual import fit_hyperparameters
from ..robot.kinematics import KinematicChain, flange_rotations
from ..robot.priors import Priors
from ..units import MM
from .settings import LoopSettings

GP = "residual_gp"
BASE_STEP = "zero-offsets (paper)"
NOISE_SEARCH_WIDTH = 3.0  # prior stds of log g either side of its median searched for the mode
MIN_GP_POSES = 10  # fewer poses than this cannot tell a smooth residual from noise
# Blocks a candidate is offered with when the model lacks them: the link geometry is complete only
# with the marker offset, which holds the tool link's error that only moves the marker
# (`blocks.structural_redundancy`); offered alone, neither explains a rigid error of the tool.
COMPANIONS = {"link_geometry": ("marker_offset",)}
# Effects offered together when each was offered alone in a round and none passed: on an elastic arm
# the sag (compliance) and the link errors trade against each other, so that each alone leaves the
# other's share in the residual and cannot win, where both together can.
PAIRS = (("joint_compliance", "link_geometry"),)


def pair_name(pair) -> str:
    """A pair's name in the candidates and rounds: 'joint_compliance + link_geometry'."""
    return " + ".join(pair)


def with_companions(candidate: str, added, remaining) -> tuple[str, ...]:
    """The blocks a candidate brings into the model: itself and its companions not yet added (and
    still offered)."""
    return (candidate,) + tuple(c for c in COMPANIONS.get(candidate, ()) if c not in added and c in remaining)


# --------------------------------------------------------------------------- accuracy measures


ACCURACY = ("rmse", "mean", "q97.5")  # of the post-registration errors (`metrics.error_summary`)


def accuracy(measured, predicted, poses) -> dict:
    """Post-registration and relative accuracy (mm) of predictions (n, 3) against measurements
    (n, 3), both in the sensor frame; poses (n,) group the relative measure's pairs
    (`remaster.inference.metrics`)."""
    error = np.asarray(measured) - np.asarray(predicted)
    measured_any = len(error) > 0  # none in a set without measured rows (a campaign without a validation set)
    norms = metrics.post_registration_errors(measured, predicted) if measured_any else np.empty(0)
    relative = metrics.relative_errors(measured, predicted, poses) if measured_any else np.empty(0)
    relative = metrics.error_summary(relative, ("mean",))
    return {
        **metrics.in_mm(metrics.error_summary(norms, ACCURACY)),
        "rms_per_axis_mm": float(metrics.rms_per_axis(error) / MM) if measured_any else float("nan"),
        "relative_pairs": relative["count"],
        "relative_mean_mm": relative["mean"] / MM if relative["count"] else None,
    }


# --------------------------------------------------------------------------- one fit


@dataclass(frozen=True, eq=False)
class Fitted:
    """One model at its posterior mode on the optimization set, with its pose-grouped
    cross-validation and the identifiability reduction of its extensions."""

    mode: evidence.PosteriorMode
    reduction: Reduction
    cv: evidence.CrossValidation
    _other_folds: dict = field(default_factory=dict, repr=False)

    def cross_validated(self, folds: np.ndarray) -> evidence.CrossValidation:
        """The cross-validation over other folds (n,) (the time blocks), computed once per folds."""
        key = np.asarray(folds).tobytes()
        if key not in self._other_folds:
            self._other_folds[key] = evidence.cross_validate(self.mode, folds)
        return self._other_folds[key]

    @property
    def model(self) -> BlockModel:
        return self.mode.model

    @property
    def theta(self) -> np.ndarray:
        return self.mode.theta

    def values(self) -> dict[str, float]:
        return self.model.values(self.theta)

    def residuals(self, data: Readings | None = None) -> np.ndarray:
        """(n, 3) measured - predicted, m, on the optimization set or other readings, with the
        optimization fit's parameters and registration."""
        return (self.model if data is None else self.model.on(data)).residuals(self.theta)

    def accuracy(self, data: Readings, poses) -> dict:
        """`accuracy` on some readings (n rows) with the optimization fit's parameters; poses (n,)."""
        model = self.model.on(data)
        return accuracy(model.measured, model.predict(self.theta), poses)


def fit_blocks(
    chain: KinematicChain,
    data: Readings,
    marker,
    t_nr,
    extensions: Sequence[str],
    base_held: Mapping[str, float],
    folds: np.ndarray,
    priors: Priors,
    start: Mapping[str, float] | None = None,
) -> Fitted:
    """Base + extensions under their priors on the optimization readings, from `start`
    ({name: value}; 0 for the others), with its cross-validation over `folds` (n,)."""
    model, reduction = blocks.extended_model(chain, data, marker, t_nr, extensions, base_held, priors)
    mode = evidence.posterior_mode(model, model.vector(start or {}))
    return Fitted(mode, reduction, evidence.cross_validate(mode, folds))


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


# The link geometry's prior scales its evidence chooses among (type-II maximum likelihood on the
# optimization set): a robot whose link errors exceed the configured priors (a degree where the prior
# says 0.1) would otherwise have them shrunk towards nominal in every weakly determined direction.
LINK_PRIOR_SCALES = (1.0, 3.0, 10.0)
LINK_PRIOR_KEYS = ("link_translation_mm", "link_rotation_deg")


def scaled_priors(priors: Priors, scale: float) -> Priors:
    """priors with the link geometry's two stds times scale (the others as they are)."""
    if scale == 1.0:
        return priors
    values = {k: (v * scale if k in LINK_PRIOR_KEYS else v) for k, v in priors.values.items()}
    return replace(priors, values=values, source=f"{priors.source}; link geometry x{scale:g} (its evidence)")


def link_prior_scale(chain, data: Readings, marker, t_nr, base_held, priors: Priors) -> tuple[float, dict]:
    """The scale of `LINK_PRIOR_SCALES` at which the model with the link geometry (and its marker
    offset) has the highest evidence on the optimization readings, and {scale: log evidence} (nats);
    (1, {}) where the model cannot be fitted."""
    evidence_at = {}
    for scale in LINK_PRIOR_SCALES:
        try:
            model, _ = blocks.extended_model(
                chain, data, marker, t_nr, ("link_geometry", "marker_offset"), base_held, scaled_priors(priors, scale)
            )
            evidence_at[scale] = float(evidence.posterior_mode(model).log_evidence)
        except np.linalg.LinAlgError:  # too few data for the model (the selection says so in its own words)
            return 1.0, {}
    return max(evidence_at, key=evidence_at.get), {f"x{k:g}": v for k, v in evidence_at.items()}


def selection_folds(poses, n_folds: int) -> np.ndarray:
    """(n,) the cross-validation folds of the selection: `n_folds` folds of whole poses, or one pose
    per fold when the campaign has fewer poses (each score carries its `cv_folds`, and the t(K - 1)
    threshold is held at that K: a campaign of few poses needs a larger fall). A single pose cannot
    be registered (`remaster.robot.registration`), so it never reaches the loop."""
    return evidence.pose_folds(poses, max(2, min(n_folds, len(np.unique(np.asarray(poses))))))


def fold_warning(poses, settings: LoopSettings) -> str | None:
    """The warning a campaign of fewer poses than `cv_folds` gets (`selection_folds`), or None."""
    n_poses, n_folds = len(np.unique(np.asarray(poses))), settings.cv_folds
    if n_poses >= n_folds:
        return None
    return (
        f"only {n_poses} poses in the optimization set: the loop closure cross-validates over {n_poses} folds "
        f"of one pose (not {n_folds}); an effect needs a fall of {cv_threshold(settings, n_poses):.3g} "
        "standard errors at the same level"
    )


def cv_threshold(settings: LoopSettings, n_folds: int | None = None) -> float:
    """The cross-validated fall (in standard errors over the folds) an effect needs: the one-sided
    level of `cv_standard_errors` normal standard errors, held at Student's t with K - 1 degrees of
    freedom (`evidence.t_threshold`; K = 5 folds at 2.0: 2.87)."""
    return evidence.t_threshold(settings.cv_standard_errors, n_folds or settings.cv_folds)


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


@dataclass(frozen=True, eq=False)
class Selection:
    """The greedy forward selection: final fit (parametric), the base fit, the rounds (JSON-ready)
    and the signatures {round: {candidate: Signature}}; gp: the Gaussian process fitted to what the
    parametric effects left (added or not: it also says where the residual lives), None when not
    tried; rotation (3, 3): the final fit's registration (robot -> sensor), which the GP's robot-frame
    correction goes through."""

    base: Fitted
    final: Fitted
    added: tuple[str, ...]
    rounds: list[dict]
    signatures: dict[int, dict[str, Signature]]
    gp: loop_candidate.Candidate | None = None
    rotation: np.ndarray | None = None
    noise: dict | None = None
    time_blocked: dict | None = None
    regions: Regions | None = None

    @property
    def gp_added(self) -> bool:
        return GP in self.added

    def prediction(self, data: Readings) -> np.ndarray:
        """(n, 3) m predicted sensor-frame positions of the selected model (parametric fit at its
        mode, plus the GP's mean when it was added) at some readings."""
        predicted = self.final.model.on(data).predict(self.final.theta)
        return predicted + self.gp.gp.mean(data.q) @ self.rotation.T if self.gp_added else predicted


@dataclass(frozen=True, eq=False)
class _Round:
    """What every candidate of one forward round is fitted from and scored against: the current fit
    (`added` its extension blocks), the data, the folds and the time blocks (`blocked`, or None)."""

    chain: KinematicChain
    data: Readings
    marker: np.ndarray
    t_nr: np.ndarray
    base_held: Mapping[str, float]
    folds: np.ndarray
    settings: LoopSettings
    blocked: np.ndarray | None
    current: Fitted
    added: tuple[str, ...]
    regions: Regions | None = None

    @cached_property
    def residual(self) -> np.ndarray:
        """The current fit's residuals (n, 3) m, once per round."""
        return self.current.residuals()

    @cached_property
    def prediction(self) -> np.ndarray:
        """The current fit's predictions (n, 3) m, once per round."""
        return self.current.model.predict(self.current.theta)

    def record(self, name: str, brings: tuple[str, ...], scores: dict, fits: dict, signatures: dict) -> None:
        """Fit the current model with the blocks `brings` and record, under `name`, its scores (or why
        it was skipped), its fit and its signature in the round's dicts."""
        current = self.current
        try:
            fitted = fit_blocks(
                self.chain, self.data, self.marker, self.t_nr, self.added + brings, self.base_held, self.folds,
                self.settings.priors, current.values(),
            )  # fmt: skip
        except np.linalg.LinAlgError as exc:
            scores[name] = {"skipped": f"not identifiable: {exc}"}
            return
        if not fitted.reduction.kept:
            scores[name] = {
                "skipped": "no parameter of this block is visible in these data",
                "dropped": dict(fitted.reduction.dropped),
            }
            return
        fits[name] = fitted
        signature = signatures[name] = Signature(self.residual, fitted.model.predict(fitted.theta) - self.prediction)
        scores[name] = {
            **score(current, fitted, self.settings, self.blocked, self.regions),
            "explained_fraction": signature.explained,
        }


def select(
    chain: KinematicChain,
    data: Readings,
    marker,
    t_nr,
    base_held: Mapping[str, float],
    poses,
    settings: LoopSettings,
    tracker: bool = False,
) -> Selection:
    """Diagnose and decide (`remaster.loop.loop_closure`, steps 1 and 2) on the optimization readings;
    poses (n,) their pose labels, which make the cross-validation folds; tracker: whether the
    sensor is a laser tracker, whose range/transverse noise is then offered."""
    folds = selection_folds(poses, settings.cv_folds)
    in_time = TimeBlocked.of(data, poses, settings.cv_folds)
    blocked = in_time.folds if in_time else None
    regions = Regions.of(chain, data, poses, settings.cv_folds)
    base = current = fit_blocks(chain, data, marker, t_nr, (), base_held, folds, settings.priors)
    remaining = [c for c in settings.candidates if blocks.available(c, data)]
    added: list[str] = []
    brought: dict[str, tuple[str, ...]] = {}  # each added block: the blocks its round brought in
    rounds, signatures = [], {}
    path = [(BASE_STEP, base)]  # every model the closure test is taken after
    while remaining:
        number = len(rounds) + 1
        scores, fits, signatures[number] = {}, {}, {}
        offered = {c: with_companions(c, added, remaining) for c in remaining}
        this = _Round(chain, data, marker, t_nr, base_held, folds, settings, blocked, current, tuple(added), regions)
        for candidate in remaining:
            this.record(candidate, offered[candidate], scores, fits, signatures[number])
        if not any(scores[c]["passed"] for c in fits):  # each alone lost: the pairs that trade against each other
            for pair in (p for p in PAIRS if all(b in fits for b in p)):
                offered[pair_name(pair)] = tuple(dict.fromkeys(b for one in pair for b in offered[one]))
                this.record(pair_name(pair), offered[pair_name(pair)], scores, fits, signatures[number])
        passing = [c for c in fits if scores[c]["passed"]]
        best = max(passing, key=lambda c: scores[c]["log_evidence_gain"]) if passing else None
        rounds.append({"round": number, "model": list(blocks.BASE) + added, "scores": scores, "added": best})
        if best is None:
            break
        current = fits[best]
        path.append((best, current))
        for member in dict(zip(map(pair_name, PAIRS), PAIRS)).get(best, (best,)):  # a pair: each its companions
            brought[member] = offered[member]
        for block in offered[best]:
            added.append(block)
            remaining.remove(block)
    forward_end = rounds[-1] if rounds else None
    current, added, backward, removed = backward_pass(
        chain, data, marker, t_nr, base_held, folds, settings, current, added, len(rounds), brought
    )
    rounds += backward
    path += removed
    # the tracker's noise shape is chosen after the residual model: before it, an anisotropic noise
    # can take up model error (a joint-space error seen from the tracker head looks transverse)
    offer_noise = tracker and settings.tracker_noise is not None
    rotation = current.model.sensor_rotation(current.theta)
    if settings.residual_gp is None or len(np.unique(poses)) < MIN_GP_POSES:
        noise_choice = None
        if offer_noise:
            current, noise_choice = choose_noise(current, folds, settings)
            path[-1] = (path[-1][0], current)
            rotation = current.model.sensor_rotation(current.theta)
        time_blocked = in_time.report(path) if in_time else None
        return Selection(
            base, current, tuple(added), rounds, signatures, None, rotation, noise_choice, time_blocked, regions
        )
    gp, scores = _score_gp(current, data, rotation, folds, settings, in_time)
    if not removed and forward_end is not None and forward_end["added"] is None:
        last = forward_end  # tried in the round where no parametric effect passed, on that round's model
    else:
        last = {"round": len(rounds) + 1, "model": list(blocks.BASE) + added, "scores": {}, "added": None}
        rounds.append(last)
    last["scores"][GP] = scores
    if scores["passed"]:
        last["added"] = GP
        current, added, gp, with_gp, removed_with_gp = residual_backward_pass(
            chain, data, marker, t_nr, base_held, folds, settings, current, gp, added, len(rounds), brought
        )
        rounds += with_gp
        path += removed_with_gp
        added.append(GP)
    noise_choice = None
    if offer_noise:
        hyper = gp.gp.hyper if GP in added else None
        try:
            current, noise_choice = choose_noise(current, folds, settings, data.q if hyper else None, hyper)
        except np.linalg.LinAlgError as exc:  # the GP-present comparison is not determined: without it, said so
            current, noise_choice = choose_noise(current, folds, settings)
            noise_choice["residual_model"] = f"residual_gp added; compared without it: {exc}"
        if noise_choice["chosen"] != "isotropic" and hyper is not None:
            gp = gp_candidate(current, data, current.model.sensor_rotation(current.theta), folds, settings)
        path[-1] = (path[-1][0], current)
    rotation = current.model.sensor_rotation(current.theta)
    time_blocked = in_time.report(path, current, data, rotation, settings) if in_time else None
    return Selection(base, current, tuple(added), rounds, signatures, gp, rotation, noise_choice, time_blocked, regions)


def removal_groups(added: Sequence[str], brought: Mapping[str, Sequence[str]] | None) -> dict[str, list[str]]:
    """{block: the blocks taken out with it} for each added block a backward pass may try out: not
    one another added block needs as its companion (`COMPANIONS`), and with the companions its
    forward round brought in (brought: {block: those blocks}) unless another block left needs them."""
    needed = {c for b in added for c in COMPANIONS.get(b, ()) if c in added}
    groups = {}
    for block in (b for b in added if b not in needed):
        others = {c for b in added if b != block for c in COMPANIONS.get(b, ())}
        groups[block] = [block] + [
            c for c in (brought or {}).get(block, ()) if c != block and c in added and c not in others
        ]
    return groups


class ForwardRuleScoring:
    """How `backward_pass` scores a block by default: as if it were offered to the model without it,
    by the forward rule (`score`), with the signature of what it explains in the model's fit."""

    round_keys: dict = {}  # what each backward round records besides its scores
    step_suffix = ""  # added to the name of each removal's step

    def __init__(self, settings: LoopSettings):
        self.settings = settings
        self._prediction = None

    def start_round(self, current: Fitted) -> None:
        """Before the blocks of a round are tried out of `current`."""
        self._prediction = current.model.predict(current.theta)

    def score(self, current: Fitted, without: Fitted) -> dict:
        """The scores (JSON-ready, with "passed") of the block `without` lacks, against `current`."""
        signature = Signature(without.residuals(), self._prediction - without.model.predict(without.theta))
        return {**score(without, current, self.settings), "explained_fraction": signature.explained}

    def removed(self, current: Fitted) -> None:
        """After a removal, `current` the model left."""


def backward_pass(
    chain: KinematicChain,
    data: Readings,
    marker,
    t_nr,
    base_held: Mapping[str, float],
    folds: np.ndarray,
    settings: LoopSettings,
    current: Fitted,
    added: Sequence[str],
    number: int,
    brought: Mapping[str, Sequence[str]] | None = None,
    scoring: ForwardRuleScoring | GPPresentScoring | None = None,
) -> tuple[Fitted, list[str], list[dict], list[tuple[str, Fitted]]]:
    """After the forward pass: each added block is tried out of the model (the rest present), the
    model refitted without it and the block scored by `scoring` (default `ForwardRuleScoring`: as if
    it were offered to the model without it, by the forward rule `passes`; `GPPresentScoring`: with
    the residual GP present, `residual_backward_pass`); of those that would not pass, the one of
    least evidence gain is removed and the pass repeated until every block left passes. A block
    another added block needs as its companion (`COMPANIONS`) is not tried alone, and a block is
    tried out together with the companions it brought into the model (brought: {block: the blocks
    its forward round added}), so that it is scored as the forward pass offered it: the link
    geometry without its marker offset explains no rigid error of the tool. number: the rounds so far.

    Returns the final fit, the blocks left (in the order added), the backward rounds (JSON-ready,
    'pass': 'backward', 'removed': the block or None; empty when nothing was added) and the
    (step name, fit) of each removal."""
    scoring = ForwardRuleScoring(settings) if scoring is None else scoring
    added, rounds, removals = list(added), [], []
    while True:
        groups = removal_groups(added, brought)
        if not groups:
            return current, added, rounds, removals
        number += 1
        scoring.start_round(current)
        scores, fits = {}, {}
        for block, group in groups.items():
            rest = tuple(b for b in added if b not in group)
            try:
                without = fit_blocks(
                    chain, data, marker, t_nr, rest, base_held, folds, settings.priors, current.values()
                )
                scores[block] = scoring.score(current, without)
            except np.linalg.LinAlgError as exc:  # the model without it is not determined: keep it
                scores[block] = {"skipped": f"the model without it is not identifiable: {exc}"}
                continue
            fits[block] = without
        failing = [b for b in fits if not scores[b]["passed"]]
        weakest = min(failing, key=lambda b: scores[b]["log_evidence_gain"]) if failing else None
        rounds.append(
            {
                "round": number,
                "pass": "backward",
                **scoring.round_keys,
                "model": list(blocks.BASE) + added,
                "scores": scores,
                "added": None,
                "removed": weakest,
                **({"removed_with": groups[weakest][1:]} if weakest and len(groups[weakest]) > 1 else {}),
            }
        )
        if weakest is None:
            return current, added, rounds, removals
        current = fits[weakest]
        for block in groups[weakest]:
            added.remove(block)
        scoring.removed(current)
        removals.append((f"without {' + '.join(groups[weakest])}{scoring.step_suffix}", current))


@dataclass(frozen=True, eq=False)
class TimeBlocked:
    """Cross-validation by blocks contiguous in time (`evidence.time_folds`) beside the pose-grouped
    folds the selection uses: how well each model predicts poses measured later (or earlier) than
    those it was fitted on, rather than among them. folds (n,); order: what the blocks follow."""

    folds: np.ndarray
    order: str

    @classmethod
    def of(cls, data: Readings, poses, n_folds: int) -> TimeBlocked | None:
        """Blocks in the order of the table's time column, or of its rows where it has none (the
        rows are then taken as the measurement order); None with fewer poses than blocks."""
        if data.drift is not None and data.drift_unit == "s":
            times, order = data.drift, "time column"
        else:
            times, order = data.rows.astype(float), "row order (no time column: taken as the measurement order)"
        try:
            return cls(evidence.time_folds(times, poses, n_folds), order)
        except ValueError:
            return None

    def report(
        self,
        path: Sequence[tuple[str, Fitted]],
        current: Fitted | None = None,
        data: Readings | None = None,
        rotation: np.ndarray | None = None,
        settings: LoopSettings | None = None,
    ) -> dict:
        """JSON-ready: the time-blocked cross-validated RMS per axis (mm) after each step of path
        ((name, fit) in order) and, given the GP's inputs, the residual GP on current's residuals
        scored over the time blocks (hyperparameters refitted without the held-out block, as with
        the pose folds): its fall, in standard errors, and its gain."""
        steps = {name: f.cross_validated(self.folds).rmse / MM / math.sqrt(3.0) for name, f in path}
        out = {
            "folds": int(len(np.unique(self.folds))),
            "order": self.order,
            "measure": "cross-validated RMS per axis, blocks of whole poses contiguous in time held out in turn",
            "rms_per_axis_mm": steps,
        }
        if current is not None:
            gain = self.gp_gain(current, data, rotation, settings)
            steps[GP] = gain["cv_rmse_mm"] / math.sqrt(3.0)
            out["residual_gp"] = {**gain, "structure_found": bool(gain["cv_mse_fall_in_se"] > cv_threshold(settings))}
        return out

    def gp_gain(self, current: Fitted, data: Readings, rotation: np.ndarray, settings: LoopSettings) -> dict:
        """The residual GP on current's residuals scored over the time blocks (hyperparameters
        refitted without the held-out block): `evidence.cv_gain` against current."""
        before = current.cross_validated(self.folds)
        gp = loop_candidate.fit_and_score(
            data.q,
            current.residuals() @ rotation,
            before.held_out @ rotation,
            self.folds,
            int(settings.residual_gp["subset"]),
            int(settings.residual_gp["inducing"]),
        )
        return evidence.cv_gain(before, evidence.CrossValidation(gp.mse, gp.points))


# Below this spread of the tool axis about its mean direction (deg) the campaign holds one tool
# orientation (a cube design's tool along one axis): regions of it would be cut from the noise of the
# inverse kinematics, not from orientations an effect could extrapolate to
TOOL_AXIS_SPREAD_DEG = 10.0
REGION_SEED = 0  # the k-means starts' seed: the same campaign is cut into the same regions


def region_features(chain: KinematicChain, q) -> dict[str, np.ndarray]:
    """The features regions are cut in, per fold set, at readings q (n, N) rad: 'joint_space' (n, 2N)
    cos and sin of each joint (a revolute joint is periodic: q and q + 2 pi are one configuration, and
    each joint's circle weighs alike), 'tool_axis' (n, 3) the flange's z axis in the robot frame (the
    tool's direction, which the joint space reaches by many configurations)."""
    q = np.asarray(q, dtype=float)
    return {
        "joint_space": np.column_stack([np.cos(q), np.sin(q)]),
        "tool_axis": flange_rotations(chain, q)[:, :, 2],
    }


@dataclass(frozen=True, eq=False)
class Regions:
    """Cross-validation by regions beside the pose folds and the time blocks: each fold a region of
    whole poses (`evidence.region_folds`, k-means of their features, `region_features`), held out in
    turn, so that a fold's fit predicts a part of the domain it did not see: what a calibration is
    bought for beyond its poses. folds: {set name: (n,) folds}; centres: {set name: (K, d)}; skipped:
    {set name: why it has no folds}."""

    folds: dict[str, np.ndarray]
    centres: dict[str, np.ndarray]
    skipped: dict[str, str]

    @classmethod
    def of(cls, chain: KinematicChain, data: Readings, poses, n_folds: int) -> Regions | None:
        """The regions of the readings' joint space and tool axis, K = n_folds of each; None with
        fewer poses than regions (then neither set can be cut)."""
        folds, centres, skipped = {}, {}, {}
        for name, features in region_features(chain, data.q).items():
            if name == "tool_axis":
                mean = features.mean(axis=0)
                mean /= max(np.linalg.norm(mean), np.finfo(float).tiny)
                spread = math.degrees(float(np.max(np.arccos(np.clip(features @ mean, -1.0, 1.0)))))
                if spread < TOOL_AXIS_SPREAD_DEG:
                    skipped[name] = f"one tool orientation (within {spread:.2g} deg of its mean)"
                    continue
            try:
                folds[name], centres[name] = evidence.region_folds(features, poses, n_folds, REGION_SEED)
            except ValueError as exc:
                skipped[name] = str(exc)
        return cls(folds, centres, skipped) if folds else None

    def report(self) -> dict:
        """JSON-ready: per fold set its regions and the rows held out in each, or why it has none."""
        return {
            "measure": "held-out regions of whole poses (k-means of the configurations' cos/sin of each joint, "
            "and of the flange's z axis); a candidate passes where the median log fall over every region is "
            "positive (`region_median_log_fall`)",
            "sets": {
                name: {"folds": len(c), "rows_per_fold": np.bincount(self.folds[name]).tolist()}
                for name, c in self.centres.items()
            },
            "skipped": dict(self.skipped),
        }


def choose_noise(
    current: Fitted,
    folds: np.ndarray,
    settings: LoopSettings,
    q=None,
    hyper: Hyperparameters | None = None,
) -> tuple[Fitted, dict]:
    """The current model with a laser tracker's range/transverse noise (`remaster.noise`) against
    its isotropic noise: g at the mode of log Z(g) + log prior(g), the model's evidence with g
    integrated by a Laplace step in log g; taken when it gains `min_log_evidence_gain`. With the
    residual GP added (its hyperparameters `hyper`, readings q (n, N)), every evidence is taken with
    the GP present (`remaster.inference.gp.with_parameters`), so the noise shape is chosen after the residual
    model, for what the residual model leaves. Returns the chosen fit and a JSON-ready report."""
    import scipy.optimize

    prior = settings.tracker_noise
    median, log_std = float(prior["growth_per_m"]), math.log(float(prior["growth_factor"]))
    gp_present = hyper is not None
    dense = gp_present and len(q) <= with_parameters.MAX_NOISE_ROWS

    def mode_at(log_growth: float) -> evidence.PosteriorMode:
        return evidence.posterior_mode(
            current.model.with_noise(noise.RangeTransverse(math.exp(log_growth))), current.theta
        )

    if gp_present:  # the parameters and the GP integrated, the noise's scale at its maximum for each shape
        unit_shapes = {None: _noise_shapes(current.model, current.model)}

        def log_z_at(log_growth: float | None) -> float:
            if log_growth not in unit_shapes:
                growth = noise.RangeTransverse(math.exp(log_growth))
                unit_shapes[log_growth] = _noise_shapes(current.model, current.model.with_noise(growth))
            shapes = unit_shapes[log_growth]
            if dense:
                at_sigma = lambda sigma: with_parameters.noise_shape_log_evidence(  # noqa: E731
                    current.mode, q, hyper, sigma**2 * shapes
                )
            else:  # through inducing inputs: the sums over rows once per shape, each sigma then cheap
                at_sigma = with_parameters.ShapedNoiseEvidence(current.mode, q, hyper, shapes)
            found = scipy.optimize.minimize_scalar(
                lambda log_sigma: -at_sigma(math.exp(log_sigma)),
                bounds=(math.log(hyper.noise_std) - 3.0, math.log(hyper.noise_std) + 3.0),
                method="bounded",
                options={"xatol": 0.01},
            )
            return -found.fun

        isotropic = log_z_at(None)
    else:

        def log_z_at(log_growth: float) -> float:
            return mode_at(log_growth).log_evidence

        isotropic = current.mode.log_evidence

    def objective(log_growth: float) -> float:
        return -(log_z_at(log_growth) + noise.log_growth_prior(log_growth, median, log_std))

    centre, width = math.log(median), NOISE_SEARCH_WIDTH * log_std
    best = scipy.optimize.minimize_scalar(
        objective, bounds=(centre - width, centre + width), method="bounded", options={"xatol": 0.05}
    )
    step = 0.1  # in log g: the posterior of log g is wider than this wherever the data leave g free
    curvature = (objective(best.x + step) - 2.0 * best.fun + objective(best.x - step)) / step**2
    curvature = max(curvature, 1.0 / log_std**2)  # the prior alone curves this much; a noisy difference may not
    log_evidence = -best.fun + 0.5 * math.log(2.0 * math.pi) - 0.5 * math.log(curvature)
    gain = log_evidence - isotropic
    mode = mode_at(best.x)
    growth = math.exp(best.x)
    distance = np.linalg.norm(current.model.measured, axis=1)
    chosen = bool(gain > settings.min_log_evidence_gain)
    report = {
        "offered": True,
        "compared": "range/transverse (laser tracker) against isotropic",
        **noise.RangeTransverse(growth).report(),
        "prior": {"growth_per_m_median": median, "growth_factor": float(prior["growth_factor"])},
        "growth_std_log": 1.0 / math.sqrt(curvature),
        "residual_model": "residual_gp present (gp_joint; the noise's scale at its maximum for each shape)"
        if dense
        else "residual_gp present (gp_joint through "
        f"{with_parameters.NOISE_INDUCING} inducing inputs above {with_parameters.MAX_NOISE_ROWS} rows, Titsias' "
        "bound; the noise's scale at its maximum for each shape)"
        if gp_present
        else "the parametric effects (no residual GP added)",
        "log_evidence_isotropic": isotropic,
        "log_evidence_range_transverse": float(log_evidence),
        "log_evidence_gain": float(gain),
        "sigma_isotropic_mm": current.mode.sigma / MM,
        "sigma_range_mm": mode.sigma / MM,
        "sigma_transverse_at_median_distance_mm": mode.sigma
        * math.sqrt(1.0 + (growth * float(np.median(distance))) ** 2)
        / MM,
        "median_distance_m": float(np.median(distance)),
        "chosen": "range_transverse" if chosen else "isotropic",
        "note": "sigma of the chosen range/transverse model is the range std; the transverse std grows with "
        "the distance from the sensor frame's origin, which must be the tracker head",
    }
    if not chosen:
        return current, report
    return Fitted(mode, current.reduction, evidence.cross_validate(mode, folds)), report


class GPPresentScoring:
    """How `residual_backward_pass` scores a block: the model with it and the model without it, each
    with the residual GP present, compared by the forward rule (`passes`) on their evidences and
    pose-grouped cross-validations with the parameters integrated together with the GP
    (`remaster.inference.gp.with_parameters`; each model's GP hyperparameters fitted to its residuals), exact
    up to `with_parameters.MAX_ROWS` rows and through inducing inputs above (`gp_method`: exact or titsias).
    Once that comparison is not determined, the parameters stay at their mode and the GP's gain on each
    model's residuals is added to its Laplace evidence (`gp_joint_fixed_mode`), which the scores say.
    `gp`: the GP on the current model's residuals, refitted after each removal."""

    round_keys = {"with": GP}
    step_suffix = f" ({GP} present)"

    def __init__(self, data: Readings, folds: np.ndarray, settings: LoopSettings, gp: loop_candidate.Candidate):
        self.data, self.folds, self.settings, self.gp = data, folds, settings, gp
        self.joint = True
        self._log_z, self._cv, self.method = None, None, None

    def _with_gp(self, fitted: Fitted, hyper: Hyperparameters) -> tuple[float, evidence.CrossValidation]:
        joint = with_parameters.with_gp(fitted.mode, self.data.q, hyper, self.folds)
        self.method = joint.method
        return joint.log_evidence, joint.cv

    @staticmethod
    def _fixed_mode(fitted: Fitted, candidate: loop_candidate.Candidate) -> tuple[float, evidence.CrossValidation]:
        return (
            fitted.mode.log_evidence + candidate.log_evidence_gain,
            evidence.CrossValidation(candidate.mse, candidate.points),
        )

    def start_round(self, current: Fitted) -> None:
        if self.joint:
            try:
                self._log_z, self._cv = self._with_gp(current, self.gp.gp.hyper)
            except np.linalg.LinAlgError:  # not determined with the GP present: the fixed-mode scores, said so
                self.joint = False
        if not self.joint:
            self._log_z, self._cv = self._fixed_mode(current, self.gp)

    def score(self, current: Fitted, without: Fitted) -> dict:
        rotation = without.model.sensor_rotation(without.theta)
        if self.joint:
            hyper = fit_hyperparameters(
                self.data.q, without.residuals() @ rotation, int(self.settings.residual_gp["subset"]), self.gp.gp.hyper
            )
            log_z_without, cv_without = self._with_gp(without, hyper)
        else:
            log_z_without, cv_without = self._fixed_mode(
                without, gp_candidate(without, self.data, rotation, self.folds, self.settings)
            )
        out = {
            "log_evidence_gain": self._log_z - log_z_without,
            "log_evidence_with_gp": self._log_z,
            "log_evidence_without_with_gp": log_z_without,
            **evidence.cv_gain(cv_without, self._cv),
            "parameters": list(current.reduction.kept),
            "evidence": "gp_joint" if self.joint else "gp_joint_fixed_mode",
            **({"gp_method": self.method} if self.joint else {}),
        }
        return judged(out, self.settings)

    def removed(self, current: Fitted) -> None:
        self.gp = gp_candidate(
            current, self.data, current.model.sensor_rotation(current.theta), self.folds, self.settings
        )


def residual_backward_pass(
    chain: KinematicChain,
    data: Readings,
    marker,
    t_nr,
    base_held: Mapping[str, float],
    folds: np.ndarray,
    settings: LoopSettings,
    current: Fitted,
    gp: loop_candidate.Candidate,
    added: Sequence[str],
    number: int,
    brought: Mapping[str, Sequence[str]] | None = None,
) -> tuple[Fitted, list[str], loop_candidate.Candidate, list[dict], list[tuple[str, Fitted]]]:
    """The parametric blocks scored again with the residual model present, once the GP is added: a
    block taken only because it absorbed part of what the GP explains (a proxy, e.g. a sensor scale
    standing in for a joint-space error) no longer passes. `backward_pass` with `GPPresentScoring`.

    Returns the final parametric fit, the blocks left, the GP on its residuals, the rounds
    (JSON-ready, 'pass': 'backward', 'with': 'residual_gp') and the (step name, fit) of each removal."""
    scoring = GPPresentScoring(data, folds, settings, gp)
    current, added, rounds, removals = backward_pass(
        chain, data, marker, t_nr, base_held, folds, settings, current, added, number, brought, scoring
    )
    return current, added, scoring.gp, rounds, removals


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


def _noise_shapes(model: BlockModel, shaped: BlockModel) -> np.ndarray:
    """(n, 3, 3): the covariance over sigma^2 of each row's noise under `shaped`'s noise model, in the
    coordinates of `model`'s whitened residuals (M (S / sigma^2) M^T, M model's whitening)."""
    unit = np.broadcast_to(np.eye(3)[:, None, :], (3, model.n_points, 3))
    whitening = np.moveaxis(model.whitened(unit), 0, -1)  # (n, 3, 3): M_i, column a = M_i e_a
    shaped_whitening = np.moveaxis(shaped.whitened(unit), 0, -1)
    inverse = np.linalg.inv(shaped_whitening)  # S_i / sigma^2 = W_i^-1 W_i^-T
    return whitening @ inverse @ np.swapaxes(inverse, 1, 2) @ np.swapaxes(whitening, 1, 2)


def _score_gp(
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
