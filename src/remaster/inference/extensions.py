"""Which extension parameters a block model carries (`extended_model`): the link-geometry
parameters absorbed at every configuration are not parameters of the robot (`structural_redundancy`),
and of the rest the data see some and not others (`identifiable_extension`).

Link geometry is complete (`parameter_blocks`); it is made minimal by the identification Jacobian
itself (`structural_redundancy`): at configurations spread over the joint limits, a parameter whose
column lies in the span of the zero-offsets, the registration and the parameters kept before it (the
marker offset, whether the model estimates it or not, and a sensor scale) is absorbed by them at
every configuration; it is not a parameter of the error model and is held at 0 (all six of F_1
against the registration, the tool's against the marker, each rotation about a joint's own axis
against its zero-offset, a translation along two parallel axes once). What is left is a parameter
of the robot; what this campaign's data cannot determine (a joint it never moved) keeps its prior.
Which extension parameters the data determine is decided in one place, `identifiable_extension`:
QR with column pivoting of the extension's Jacobian columns after projecting out the base
parameters' columns.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..noise import RangeTransverse
from ..robot.kinematics import KinematicChain
from ..robot.priors import Priors
from .blocks import BlockModel
from .identifiability import JACOBIAN_STEP
from .parameter_blocks import BASE
from .readings import Readings

# An extension column of the Jacobian below this fraction of the longest of its own block is
# invisible in the data: e.g. the compliance of joint 1 about the vertical (zero torque), the
# scale of a joint that never moves. Within a block, so that the choice of units does not matter.
INVISIBLE = 1e-6
# An extension column whose part outside the span of the base and of the extension columns
# already kept is below this fraction of its length (the sine of its angle to that span) is
# absorbed EXACTLY by them (the first link's length by the registration's z, the marker's
# tangential offset by the last zero-offset): held at 0, as the paper's joint 1 is. Any larger
# sine is kept: its Gaussian prior, not a threshold, decides how far the data may move it.
ABSORBED = 1e-6
# Configurations over the joint limits at which structural redundancy is decided
# (`structural_redundancy`): a Halton sequence, the same every run, enough to move every joint
# through many combinations of the others for chains of up to a dozen joints.
STRUCTURAL_CONFIGURATIONS = 96
# The blocks that take part in deciding structural redundancy (`structural_redundancy`): only
# link-geometry parameters are dropped for structure; the marker offset and a sensor scale are
# quantities of the set-up, part of the span they are tested against.
GEOMETRIC = ("marker_offset", "sensor_scale", "link_geometry", "sensor_distortion")
# Below this sine a kept parameter is weakly determined (its std alone would grow more than a
# thousandfold): reported, so that a reader knows its prior is doing the work.
COLLINEAR = 1e-3


@dataclass(frozen=True)
class Reduction:
    """Which extension parameters the data can see at all. kept: free extension parameters (each
    under its prior); dropped: {name: why} the data cannot see ('invisible' with its relative size,
    or 'absorbed' exactly by the base and the parameters kept before it, with the sine of its angle
    to their span): held at 0 without priors, carried by their prior with them (`extended_model`);
    structural: the dropped link-geometry parameters absorbed at EVERY configuration (not
    parameters of the error model: always held at 0); weak: {name: sine} of kept parameters the
    data barely separate (sine below COLLINEAR: their prior decides them); condition_number of the
    whole model's free Jacobian with unit-length columns (so independent of units)."""

    kept: tuple[str, ...]
    dropped: dict[str, str]
    condition_number: float
    weak: dict[str, float] = field(default_factory=dict)
    structural: tuple[str, ...] = ()

    def report(self) -> dict:
        return {
            "kept": list(self.kept),
            "dropped": dict(self.dropped),
            "structurally_absorbed": list(self.structural),
            "weakly_determined_sine": dict(self.weak),
            "condition_number_unit_columns": self.condition_number,
            "method": "Gram-Schmidt (QR) of the extension's unit-length Jacobian columns in model order, from "
            "the span of the base columns; 'dropped' = the data cannot see it (held at 0 without a prior, "
            "left to its prior with one); 'structurally_absorbed' = link-geometry parameters the zero-offsets, "
            f"registration and the parameters before them absorb at {STRUCTURAL_CONFIGURATIONS} configurations "
            "spread over the joint limits (held at 0 always)",
            "invisible_below": INVISIBLE,
            "absorbed_below": ABSORBED,
            "weak_below": COLLINEAR,
        }


def spread_configurations(chain: KinematicChain, count: int = STRUCTURAL_CONFIGURATIONS) -> np.ndarray:
    """(count, N) configurations spread over the joint limits, [-pi, pi] for a joint without finite
    ones: an unscrambled Halton sequence (deterministic, no generator), its first point (the lower
    corner) skipped."""
    from scipy.stats import qmc

    unit = qmc.Halton(d=chain.n_joints, scramble=False).random(count + 1)[1:]
    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    return lower + unit * (upper - lower)


def _range_basis(columns: np.ndarray) -> np.ndarray:
    """Orthonormal basis (3n, r) of the span of columns (3n, k), rank-deficient ones included (a
    zero-offset the registration absorbs): singular vectors above ABSORBED x the largest."""
    if columns.shape[1] == 0:
        return np.zeros((columns.shape[0], 0))
    norms = np.linalg.norm(columns, axis=0)
    unit = columns[:, norms > 0] / norms[norms > 0]
    u, singular, _ = np.linalg.svd(unit, full_matrices=False)
    return u[:, singular > ABSORBED * singular[0]] if singular.size else u[:, :0]


def structural_redundancy(model: BlockModel) -> dict[str, str]:
    """{name: why} of the model's free link-geometry parameters that the zero-offsets (all of
    them, free), the registration, the marker offset (always: the tool's link error that only moves
    the marker is the marker's offset, in a model that has one or not) and the geometric parameters
    before them (sensor scale, earlier link parameters kept) absorb at every configuration:
    Gram-Schmidt of their unit-length Jacobian columns at `spread_configurations`, in model order;
    a column whose sine to that span is below ABSORBED is absorbed, and `why` names the parameters
    that absorb it."""
    if not any(model.block_of[n] == "link_geometry" for n in model.names):
        return {}
    q = spread_configurations(model.chain)
    zeros = np.zeros_like(q)
    probe_data = Readings(np.arange(len(q)), q, np.zeros((len(q), 3)), zeros, zeros)
    # the marker offset always takes part: where the marker sits on the tool is the marker's
    # parameter, not the tool link's, whether or not this model estimates it
    geometric = [b for b in model.blocks[len(BASE) :] if b in GEOMETRIC] + ["marker_offset"]
    probe = BlockModel(model.chain, probe_data, model.marker, model.t_nr, geometric)
    jacobian = probe.jacobian(np.zeros(len(probe.names)), JACOBIAN_STEP)
    lengths = np.linalg.norm(jacobian, axis=0)
    is_link = np.array([probe.block_of[n] == "link_geometry" for n in probe.names])
    candidates = set(n for n in model.names if model.block_of[n] == "link_geometry")
    kept = list(np.flatnonzero(~is_link))
    span = _range_basis(jacobian[:, kept])
    out = {}
    for i in np.flatnonzero(is_link):
        name = probe.names[i]
        if name not in candidates:
            continue
        unit = jacobian[:, i] / lengths[i] if lengths[i] > 0 else jacobian[:, i]
        outside = unit - span @ (span.T @ unit)
        outside = outside - span @ (span.T @ outside)  # twice: one pass loses orthogonality to rounding
        sine = float(np.linalg.norm(outside))
        if sine > ABSORBED:
            kept.append(i)
            span = np.column_stack([span, outside / sine])
            continue
        basis = jacobian[:, kept]
        weights = np.linalg.lstsq(basis, jacobian[:, i], rcond=None)[0] * np.linalg.norm(basis, axis=0)
        largest = np.argsort(-np.abs(weights))[:3]
        by = ", ".join(probe.names[kept[k]] for k in largest if abs(weights[k]) > 1e-3 * max(lengths[i], 1e-300))
        out[name] = f"absorbed at every configuration by {by or 'nothing: no effect'} (sine {sine:.1e})"
    return out


def identifiable_extension(model: BlockModel, theta=None) -> Reduction:
    """Which of the model's free extension parameters the data can see, at theta (default 0).

    From the Jacobian: a column shorter than INVISIBLE x the longest of its block is invisible.
    The others, scaled to unit length, go through Gram-Schmidt (QR) in the model's order,
    starting from the span of the base columns: a column whose sine to the span of the base and
    the columns kept before it is below ABSORBED is absorbed exactly (held at 0, like joint 1's
    zero-offset against the registration); every other one is kept, under its prior, and marked
    weak below COLLINEAR. The order is a priority: a block's main parameters come before its
    secondary ones (a compliance before its payload correction).
    """
    theta = np.zeros(len(model.names)) if theta is None else np.asarray(theta, dtype=float)
    jacobian = model.jacobian(theta, JACOBIAN_STEP)
    is_base = np.array([model.block_of[n] in BASE for n in model.names])
    ext_names = [n for n, b in zip(model.names, is_base) if not b]
    ext = jacobian[:, ~is_base]
    lengths = np.linalg.norm(ext, axis=0)
    longest = {}
    for name, length in zip(ext_names, lengths):
        longest[model.block_of[name]] = max(longest.get(model.block_of[name], 0.0), length)
    span, _ = np.linalg.qr(jacobian[:, is_base])
    kept, dropped, weak = [], {}, {}
    for i, name in enumerate(ext_names):
        relative = lengths[i] / longest[model.block_of[name]] if lengths[i] > 0 else 0.0
        if relative < INVISIBLE:
            dropped[name] = f"invisible: effect {relative:.1e} of the block's largest"
            continue
        outside = ext[:, i] / lengths[i] - span @ (span.T @ ext[:, i] / lengths[i])
        sine = float(np.linalg.norm(outside))
        if sine > ABSORBED:
            kept.append(i)
            span = np.column_stack([span, outside / sine])
            if sine < COLLINEAR:
                weak[name] = sine
        else:
            dropped[name] = f"absorbed: sine {sine:.1e} to the base and the parameters kept before it"
    keep = is_base.copy()
    keep[np.flatnonzero(~is_base)[kept]] = True
    columns = jacobian[:, keep]
    norms = np.linalg.norm(columns, axis=0)
    # a base column without any effect (a zero-offset of a joint the marker sits on, not held here)
    # makes the kept set singular; the others are scaled to unit length
    singular = np.linalg.svd(columns[:, norms > 0] / norms[norms > 0], compute_uv=False)
    condition = float(singular[0] / singular[-1]) if np.all(norms > 0) else np.inf
    return Reduction(tuple(ext_names[i] for i in kept), dropped, condition, weak)


def extended_model(
    chain: KinematicChain,
    data: Readings,
    marker,
    t_nr,
    blocks: Sequence[str],
    base_held: Mapping[str, float],
    priors: Priors | None = None,
    noise: RangeTransverse | None = None,
) -> tuple[BlockModel, Reduction]:
    """The model of base + blocks, under `priors`, with the base's held parameters held and the
    link-geometry parameters absorbed at every configuration held at 0 (`structural_redundancy`:
    they are not parameters of the robot). Under priors every other extension parameter is kept,
    those the data cannot see included: their prior carries them, so what they do away from the
    measured configurations (a joint that never moved, a tool that never turned) stays in the
    posterior. Without priors (flat), the parameters the data cannot see at all are held at 0 too.
    The reduction reports which are which."""
    structural = structural_redundancy(BlockModel(chain, data, marker, t_nr, blocks, base_held))
    held = {**dict(base_held), **{n: 0.0 for n in structural}}
    found = identifiable_extension(BlockModel(chain, data, marker, t_nr, blocks, held))
    reduction = Reduction(
        found.kept, {**structural, **found.dropped}, found.condition_number, found.weak, tuple(structural)
    )
    if priors is None:
        held = {**held, **{n: 0.0 for n in found.dropped}}
    return BlockModel(chain, data, marker, t_nr, blocks, held, priors, noise), reduction
