"""The backward pass: each added block tried out of the model and scored, the weakest that would
not pass removed, until every block left passes; by the forward rule (`ForwardRuleScoring`), or with
the residual Gaussian process present once it is added (`GPPresentScoring`,
`residual_backward_pass`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..inference import evidence
from ..inference.gp import loop_candidate, with_parameters
from ..inference.gp.kernels import Hyperparameters
from ..inference.gp.residual import fit_hyperparameters
from ..inference.parameter_blocks import BASE
from ..inference.readings import Readings
from ..robot.kinematics import KinematicChain
from .candidates import COMPANIONS, GP
from .fitted import Fitted, fit_blocks
from .residual_gp import gp_candidate
from .scoring import Signature, judged, score
from .settings import LoopSettings


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
                "model": list(BASE) + added,
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
