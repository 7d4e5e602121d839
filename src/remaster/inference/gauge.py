"""Sampling coordinates with the measurement's exact symmetries folded out.

Turning the marker about the last joint's axis is turning that joint's zero-offset: the data see
only the combination, the marker's prior decides the rest. The trade is a rotation, so in the
model's own parameters (flange-frame x, y, z) it is a curved ridge, as long as the prior and as thin
as the data: a Laplace approximation cannot follow it, and an independence proposal drawn from one
is nearly always refused off it. In cylindrical coordinates about the last joint's axis the ridge is
straight and the posterior is close to Gaussian. (The link-geometry errors that the registration or
the marker absorb at every configuration, those of the base link and of the tool, are not
parameters of the model at all: `extensions.structural_redundancy` holds them.) `Gauge` maps parameter
vectors both ways with the log-Jacobian that keeps the posterior the same; `FoldedTarget` is a
sampler target in the folded coordinates, and `Gauge.back` returns its chains in the model's own
parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..robot.kinematics import KinematicChain
from .parameter_blocks import MARKER_OFFSET as MARKER
from .sampling.target import Chain, Target

TURNED = ("marker_offset.radial", "marker_offset.tangential", "marker_offset.axial")
MIN_RADIUS_IN_STD = 5.0  # polar coordinates need the marker well off the axis: its radius >> its spread
JACOBIAN_STEP = 1e-6  # of a parameter's step unit (`Target.scale`), for the Laplace's change of coordinates


def last_axis(chain: KinematicChain) -> tuple[np.ndarray, np.ndarray]:
    """The last joint's axis in the flange frame: a point (3,) m on it and its unit direction (3,).
    (The chain is F_1 R_1(q_1) ... F_N R_N(q_N) F_tool: the axis passes through joint N's origin.)"""
    rotation, shift = chain.tool_transform[:3, :3], chain.tool_transform[:3, 3]
    return -rotation.T @ shift, rotation.T @ chain.joint_axes[-1]


@dataclass(frozen=True)
class MarkerTurn:
    """Cylindrical coordinates of the marker offset about an axis, at positions `index` (3,) of a
    parameter vector: (radial, tangential arc, axial), all in metres, zero at the nominal marker.

    marker (3,) m: the nominal marker, flange frame; centre (3,) m and axis (3,) unit: the axis;
    radial, tangential (3,): unit vectors at the nominal marker (radial, axis x radial)."""

    index: np.ndarray
    marker: np.ndarray
    centre: np.ndarray
    axis: np.ndarray
    radial: np.ndarray
    tangential: np.ndarray
    radius: float

    @classmethod
    def about(cls, index, marker, centre, axis) -> MarkerTurn:
        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        relative = np.asarray(marker, dtype=float) - centre
        in_plane = relative - (relative @ axis) * axis
        radius = float(np.linalg.norm(in_plane))
        radial = in_plane / radius if radius > 0 else np.zeros(3)
        return cls(
            np.asarray(index),
            np.asarray(marker, dtype=float),
            np.asarray(centre, dtype=float),
            axis,
            radial,
            np.cross(axis, radial),
            radius,
        )

    def fold(self, theta) -> np.ndarray:
        """Vectors (..., P) with the offset in x, y, z -> the same with it in radial, tangential, axial."""
        theta = np.array(theta, dtype=float)
        relative = self.marker + theta[..., self.index] - self.centre
        along = relative @ self.axis
        in_plane = relative - along[..., None] * self.axis
        angle = np.arctan2(in_plane @ self.tangential, in_plane @ self.radial)
        theta[..., self.index] = np.stack(
            [
                np.linalg.norm(in_plane, axis=-1) - self.radius,
                self.radius * angle,
                along - (self.marker - self.centre) @ self.axis,
            ],
            axis=-1,
        )
        return theta

    def unfold(self, turned) -> tuple[np.ndarray, np.ndarray]:
        """The inverse of `fold`, and log |d(x, y, z) / d(radial, tangential, axial)| = log(rho / r),
        -inf where rho <= 0 (outside the map's range)."""
        turned = np.array(turned, dtype=float)
        radial, arc, axial = np.moveaxis(turned[..., self.index], -1, 0)
        rho, angle = self.radius + radial, arc / self.radius
        point = (
            self.centre
            + ((self.marker - self.centre) @ self.axis + axial)[..., None] * self.axis
            + rho[..., None] * (np.cos(angle)[..., None] * self.radial + np.sin(angle)[..., None] * self.tangential)
        )
        turned[..., self.index] = point - self.marker
        with np.errstate(divide="ignore", invalid="ignore"):
            return turned, np.where(rho > 0, np.log(np.abs(rho) / self.radius), -np.inf)


@dataclass(frozen=True)
class Gauge:
    """The folds that apply to a model's parameters (`Gauge.of`), composed: `fold` applies them
    in order, `unfold` undoes them in reverse. names: the model's parameter names."""

    folds: tuple
    names: tuple[str, ...]

    @classmethod
    def of(cls, names, chain: KinematicChain, marker, t_nr, covariance, turn_marker: bool = True) -> Gauge | None:
        """The folds for free parameters `names` (sigma last) of a model on `chain` with marker (3,)
        m and initial registration t_nr (4, 4), or None when none applies. The marker is turned
        (if turn_marker) only when its offset is free in x, y, z and it lies more than
        MIN_RADIUS_IN_STD times its spread (covariance (P, P), e.g. the Laplace approximation's)
        from the axis."""
        names = tuple(names)
        folds = []
        if set(MARKER) <= set(names) and turn_marker:
            index = np.array([names.index(n) for n in MARKER])
            turn = MarkerTurn.about(index, marker, *last_axis(chain))
            in_plane = np.column_stack([turn.radial, turn.tangential])
            spread = np.sqrt(np.linalg.eigvalsh(in_plane.T @ covariance[np.ix_(index, index)] @ in_plane).max())
            if turn.radius > MIN_RADIUS_IN_STD * spread:
                folds.append(turn)
        return cls(tuple(folds), names) if folds else None

    @property
    def folded_names(self) -> tuple[str, ...]:
        out = list(self.names)
        for fold in self.folds:
            for i, name in zip(
                fold.index, TURNED if isinstance(fold, MarkerTurn) else (out[i] + "~" for i in fold.index)
            ):
                out[i] = name
        return tuple(out)

    def fold(self, theta) -> np.ndarray:
        """Model parameters (..., P) -> folded coordinates (..., P)."""
        out = np.array(theta, dtype=float)
        for fold in self.folds:
            out = fold.fold(out)
        return out

    def unfold(self, folded) -> tuple[np.ndarray, np.ndarray]:
        """Folded coordinates (..., P) -> model parameters (..., P) and log |d model / d folded| (...,)."""
        out, log_jacobian = np.array(folded, dtype=float), np.zeros(np.shape(folded)[:-1])
        for fold in reversed(self.folds):
            out, part = fold.unfold(out)
            log_jacobian = log_jacobian + part
        return out, log_jacobian

    def laplace(self, mean, covariance, scale) -> tuple[np.ndarray, np.ndarray]:
        """A Gaussian approximation (mean (P,), covariance (P, P)) carried into the folded
        coordinates by the map's Jacobian at the mean (central differences of JACOBIAN_STEP x
        scale (P,))."""
        folded = self.fold(mean)
        steps = JACOBIAN_STEP * np.asarray(scale, dtype=float)
        shifted = folded + np.concatenate([np.diag(steps), -np.diag(steps)])
        model, _ = self.unfold(shifted)
        jacobian = ((model[: len(steps)] - model[len(steps) :]) / (2 * steps)[:, None]).T
        inverse = np.linalg.inv(jacobian)
        return folded, inverse @ covariance @ inverse.T

    def back(self, chain: Chain) -> Chain:
        """A chain run on `FoldedTarget`, in the model's own parameters and log-posterior."""
        samples, log_jacobian = self.unfold(chain.samples)
        return replace(chain, samples=samples, log_prob=chain.log_prob - log_jacobian, names=self.names)


@dataclass(frozen=True, eq=False)
class FoldedTarget:
    """`target`'s posterior in the folded coordinates: log p(unfold(u)) + log |d unfold / d u|."""

    target: Target
    gauge: Gauge

    @property
    def names(self) -> tuple[str, ...]:
        return self.gauge.folded_names

    @property
    def scale(self) -> np.ndarray:
        return self.target.scale

    def log_prob(self, folded) -> float:
        return float(self.log_prob_many(np.asarray(folded, dtype=float)[None, :])[0])

    def log_prob_many(self, folded) -> np.ndarray:
        theta, log_jacobian = self.gauge.unfold(np.asarray(folded, dtype=float))
        out = np.full(len(theta), -np.inf)
        inside = np.isfinite(log_jacobian)
        if inside.any():
            out[inside] = self.target.log_prob_many(theta[inside]) + log_jacobian[inside]
        return out


LAPLACE_CHECK_DRAWS = 256  # per option: the log-weights' spread to a few per cent, ~5 % of a refit's evaluations


def laplace_mismatch(
    target: Target, mean, covariance, rng: np.random.Generator, draws: int = LAPLACE_CHECK_DRAWS
) -> float:
    """How far a posterior is from its Gaussian approximation N(mean (P,), covariance (P, P)):
    the standard deviation of log p(x) - log N(x) over draws from it (0 for a Gaussian posterior;
    an independence sampler's acceptance falls fast as it grows past 1). inf when a draw falls
    outside the support."""
    factor = np.linalg.cholesky(covariance)
    z = rng.standard_normal((draws, len(mean)))
    log_weights = target.log_prob_many(mean + z @ factor.T) + 0.5 * np.sum(z * z, axis=1)
    return float(np.std(log_weights)) if np.all(np.isfinite(log_weights)) else np.inf


def sampling_coordinates(
    target: Target, model, mean, covariance, rng: np.random.Generator
) -> tuple[Target, np.ndarray, np.ndarray, Gauge | None, dict]:
    """The coordinates in which `target` (a `posterior_targets.PosteriorTarget` of a block model) is closest to
    its Laplace approximation (mean (P,), covariance (P, P), model parameters): the model's own, or
    the marker turned about the last joint's axis where that applies (it straightens the marker's
    trade with the last joint but bends its trade with the registration, the one a campaign whose
    tool never turns has: the mismatch decides). Returns the target, mean and covariance in the
    chosen coordinates, the gauge (None: the model's own) and a JSON-ready report of each option's
    mismatch."""
    options = {"model parameters": None}
    folded = Gauge.of(target.names, model.chain, model.marker, model.t_nr, covariance)
    if folded is not None:
        options["folded"] = folded
    mismatch, laplace = {}, {}
    for label, gauge in options.items():
        laplace[label] = (mean, covariance) if gauge is None else gauge.laplace(mean, covariance, target.scale)
        folded = target if gauge is None else FoldedTarget(target, gauge)
        mismatch[label] = laplace_mismatch(folded, *laplace[label], rng)
    chosen = min(mismatch, key=mismatch.get)
    gauge = options[chosen]
    report = {
        "chosen": chosen,
        "folds": [type(f).__name__ for f in gauge.folds] if gauge else [],
        "laplace_log_weight_std": mismatch,
    }
    return (target if gauge is None else FoldedTarget(target, gauge)), *laplace[chosen], gauge, report
