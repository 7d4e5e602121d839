"""Diagnose and decide (`remaster.loop.loop_closure`, steps 1 and 2): every candidate effect fitted at
its posterior mode on the optimization set (`fitted`), scored by its evidence gain, its pose-grouped
cross-validation, its cross-validation over blocks contiguous in time and over held-out regions of
the domain (`held_out`) and its signature (`scoring`), and added greedily while one passes; a
backward pass (`backward`); the residual Gaussian process over the joints (`residual_gp`), and with
it added the parametric blocks scored again with the GP present; last a laser tracker's
range/transverse noise (`tracker_noise`), for what the residual model leaves.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..inference.gp import loop_candidate
from ..inference.parameter_blocks import BASE, available
from ..inference.readings import Readings
from ..robot.kinematics import KinematicChain
from .backward import backward_pass, residual_backward_pass
from .candidates import GP, PAIRS, pair_name, with_companions
from .fitted import Fitted, fit_blocks
from .held_out import Regions, TimeBlocked, selection_folds
from .residual_gp import gp_candidate, score_gp
from .scoring import Signature, score
from .settings import LoopSettings
from .tracker_noise import choose_noise

BASE_STEP = "zero-offsets (paper)"
MIN_GP_POSES = 10  # fewer poses than this cannot tell a smooth residual from noise


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
    tracker: float | None = None,
) -> Selection:
    """Diagnose and decide (`remaster.loop.loop_closure`, steps 1 and 2) on the optimization readings;
    poses (n,) their pose labels, which make the cross-validation folds; tracker: where the sensor is
    a laser tracker whose range/transverse noise is offered (`choose_noise`), the instrument's noise
    floor (m; inf when it is not known), else None."""
    folds = selection_folds(poses, settings.cv_folds)
    in_time = TimeBlocked.of(data, poses, settings.cv_folds)
    blocked = in_time.folds if in_time else None
    regions = Regions.of(chain, data, poses, settings.cv_folds)
    base = current = fit_blocks(chain, data, marker, t_nr, (), base_held, folds, settings.priors)
    remaining = [c for c in settings.candidates if available(c, data)]
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
        rounds.append({"round": number, "model": list(BASE) + added, "scores": scores, "added": best})
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
    offer_noise = tracker is not None and settings.tracker_noise is not None
    floor = tracker if tracker is not None and math.isfinite(tracker) else None
    rotation = current.model.sensor_rotation(current.theta)
    if settings.residual_gp is None or len(np.unique(poses)) < MIN_GP_POSES:
        noise_choice = None
        if offer_noise:
            current, noise_choice = choose_noise(current, folds, settings, floor=floor)
            path[-1] = (path[-1][0], current)
            rotation = current.model.sensor_rotation(current.theta)
        time_blocked = in_time.report(path) if in_time else None
        return Selection(
            base, current, tuple(added), rounds, signatures, None, rotation, noise_choice, time_blocked, regions
        )
    gp, scores = score_gp(current, data, rotation, folds, settings, in_time)
    if not removed and forward_end is not None and forward_end["added"] is None:
        last = forward_end  # tried in the round where no parametric effect passed, on that round's model
    else:
        last = {"round": len(rounds) + 1, "model": list(BASE) + added, "scores": {}, "added": None}
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
            current, noise_choice = choose_noise(current, folds, settings, data.q if hyper else None, hyper, floor)
        except np.linalg.LinAlgError as exc:  # the GP-present comparison is not determined: without it, said so
            current, noise_choice = choose_noise(current, folds, settings, floor=floor)
            noise_choice["residual_model"] = f"residual_gp added; compared without it: {exc}"
        if noise_choice["chosen"] != "isotropic" and hyper is not None:
            gp = gp_candidate(current, data, current.model.sensor_rotation(current.theta), folds, settings)
        path[-1] = (path[-1][0], current)
    rotation = current.model.sensor_rotation(current.theta)
    time_blocked = in_time.report(path, current, data, rotation, settings) if in_time else None
    return Selection(base, current, tuple(added), rounds, signatures, gp, rotation, noise_choice, time_blocked, regions)
