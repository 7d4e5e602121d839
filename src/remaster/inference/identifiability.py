"""Which parameter combinations the data cannot determine, found before any sampling.

The singular values of the identification Jacobian (d residuals / d parameters) say it: an
(almost) zero singular value is a direction along which the residuals do not change, so a flat
prior gives an improper posterior along it. remaster never reports such a direction with a
spurious small std: for each one it holds one parameter at its controller value (a zero
correction) and says so.

The test is the one `samplers.least_squares_laplace` applies to the fit that follows
(`samplers.undetermined_directions`): singular values of the Jacobian in step units (J * scale:
mm and deg, so that the test does not depend on metres against radians) below `samplers.RCOND`
times the largest. Holding by a different test would leave combinations between the two tests
neither held nor allowed, and the Laplace fit would stop on them (NotIdentifiable); so the
analysis also checks that the parameters it leaves free pass that test, and holds more until
they do. It holds below MARGIN x RCOND: the fit tests at its optimum, a fraction of a degree
from where the analysis tests, and a singular value just above the threshold here must not fall
just below it there.

Which parameter is held for a direction: a zero-offset taking part in it (the one with the
largest share), because the registration must stay free to place the sensor; when no zero-offset
takes part (a registration the data cannot pin down, e.g. points on a line leave the rotation
about that line and the translations that go with it undetermined), the registration parameter
with the largest share. On the iiwa with a free six-parameter registration this is joint 1: its
offset is a rotation about the base Z axis that the registration absorbs exactly. A joint that
never moves ahead of every other joint (joint 1 always at the same reading) makes the next
joint's offset a rigid rotation too; a marker on the last joint's axis makes that joint's offset
invisible; the analysis finds each the same way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .model import display_unit
from .samplers import RCOND, undetermined_directions

# Central differences with a 1e-6 rad/m step are exact to ~1e-10 relative, so a true null
# direction sits many decades below RCOND, and a merely weak one (1e-4 and up) far above it.
JACOBIAN_STEP = 1e-6
# The analysis's threshold is this multiple of the fit's: singular values move by far less than
# a factor of 2 between zero corrections and the optimum, and a combination between 1 and 2 x
# RCOND (a std over 5e5 times the best-determined one's) loses nothing by being held.
MARGIN = 2.0
RELATIVE_THRESHOLD = MARGIN * RCOND
# A parameter takes part in a direction when its component (step units) is at least this
# fraction of the direction's largest: holding it then leaves the others a singular value
# about this fraction of its column's, decades above RCOND.
PART = 1e-3


@dataclass(frozen=True)
class Identifiability:
    """names (P,): the parameters analysed; singular_values (P,) of the Jacobian in step units
    (J * scale: per mm or per deg), largest first; null_directions: one {name: component} per
    undetermined combination (step units, largest component +-1); held: {name: value} the
    parameters held to remove them; combinations: {held name: {name: weight}}, the combination
    each held parameter stood for (step units, its own weight 1: one mm or deg of it is undone by
    `weight` mm or deg of each other); condition_number of the step-unit Jacobian of the
    parameters left free; rcond: the test's threshold."""

    names: tuple[str, ...]
    singular_values: np.ndarray
    null_directions: tuple[dict[str, float], ...]
    held: dict[str, float]
    condition_number: float
    combinations: dict[str, dict[str, float]]
    rcond: float = RELATIVE_THRESHOLD

    def statements(self) -> list[str]:
        """One plain sentence per held parameter: what the data cannot tell apart."""
        out = []
        for name, combination in self.combinations.items():
            others = [f"{w:+.3g} {display_unit(n)} of {n}" for n, w in combination.items() if n != name]
            undone = ("is undone by " + ", ".join(others)) if others else "changes no measured point"
            out.append(
                f"{name} is held at the controller's value: 1 {display_unit(name)} of it {undone} "
                f"(singular value of the step-unit Jacobian below {self.rcond:g} x the largest)"
            )
        return out

    def report(self) -> dict:
        """A JSON-ready account of the analysis."""
        return {
            "parameters": list(self.names),
            "singular_values": self.singular_values.tolist(),
            "units": "step units: the Jacobian's columns per mm (registration.x, y, z) or per deg (the rest)",
            "relative_threshold": self.rcond,
            "null_directions": [dict(d) for d in self.null_directions],
            "held_at_controller_value": dict(self.held),
            "held_combinations": {name: dict(c) for name, c in self.combinations.items()},
            "statements": self.statements(),
            "condition_number_free": self.condition_number,
            "note": (
                "each held parameter is not identifiable from these data: its posterior under a flat prior "
                "is improper, so it is held at the controller's value (zero correction) rather than "
                "reported with a spurious uncertainty; the test is the Laplace fit's (singular values of "
                "the Jacobian in step units below relative_threshold x the largest)"
            ),
        }


def _direction(vector: np.ndarray, names, unit: int | None = None) -> dict[str, float]:
    """{name: component} of a direction, scaled so that component `unit` (default the largest in
    size) is +1; components below PART of the largest left out."""
    top = np.max(np.abs(vector))
    pivot = int(np.argmax(np.abs(vector))) if unit is None else unit
    scaled = vector / vector[pivot]
    return {n: float(c) for n, c in zip(names, scaled) if abs(c) * abs(vector[pivot]) >= PART * top}


def _choose(basis: np.ndarray, names, taken: set[int]) -> int:
    """The parameter to hold for one direction of the null space (basis (P, k), orthonormal
    columns): the zero-offset with the largest share of it, else the registration parameter
    with the largest, else any; never one already taken."""
    share = np.linalg.norm(basis, axis=1)
    share[list(taken)] = -1.0
    top = share.max()
    for prefix in ("zero_offsets.", "registration.", ""):
        pool = [i for i, n in enumerate(names) if n.startswith(prefix) and share[i] >= PART * top]
        if pool:
            return max(pool, key=lambda i: share[i])
    raise AssertionError("a non-empty null space has a parameter taking part in it")


def hold_undetermined(
    jacobian, names, scale, rcond: float = RELATIVE_THRESHOLD
) -> tuple[dict[str, dict[str, float]], list[dict[str, float]]]:
    """({held name: its combination}, null directions found) for a Jacobian (k, P) SI of
    parameters `names` with step units `scale` (P,): one parameter held per direction the
    step-unit test finds, then the test repeated on the parameters left free until it passes
    (round-off can leave a direction near the threshold once others are gone)."""
    jacobian = np.asarray(jacobian, dtype=float)
    scale = np.asarray(scale, dtype=float)
    names = list(names)
    combinations: dict[str, dict[str, float]] = {}
    directions: list[dict[str, float]] = []
    free = list(range(len(names)))
    for _ in range(len(names)):
        if not free:
            break
        _, vt, small = undetermined_directions(jacobian[:, free], scale[free], rcond)
        if not small.any():
            return combinations, directions
        free_names = [names[i] for i in free]
        basis = vt[small].T  # (free, k): the null space in step units
        directions += [_direction(v, free_names) for v in basis.T]
        taken: set[int] = set()
        while basis.shape[1]:
            i = _choose(basis, free_names, taken)
            combinations[free_names[i]] = _direction(basis @ basis[i], free_names, unit=i)
            taken.add(i)
            # the null space left once parameter i is held: its vectors without a component on i
            _, _, rows = np.linalg.svd(basis[i][None, :])
            basis = basis @ rows[1:].T
        free = [i for i in free if names[i] not in combinations]
    if free:
        _, _, small = undetermined_directions(jacobian[:, free], scale[free], rcond)
        if not small.any():
            return combinations, directions
    raise RuntimeError("holding one parameter per null direction did not make the rest identifiable")


class LinearisedModel(Protocol):
    """What the analysis needs of a model (a `blocks.BlockModel`, which imports this module's
    JACOBIAN_STEP): its parameter names and scales, and its Jacobian at theta."""

    names: list[str]
    scale: np.ndarray

    def weighted_jacobian(self, theta: np.ndarray, step: float) -> np.ndarray: ...


def analyse(model: LinearisedModel, rcond: float = RELATIVE_THRESHOLD) -> Identifiability:
    """Analyse a model whose parameters are all free, at zero corrections."""
    theta = np.zeros(len(model.names))
    jacobian = model.weighted_jacobian(theta, JACOBIAN_STEP)  # a full-pose probe's orientations included
    singular, _, _ = undetermined_directions(jacobian, model.scale, rcond)
    combinations, directions = hold_undetermined(jacobian, model.names, model.scale, rcond)
    keep = [i for i, n in enumerate(model.names) if n not in combinations]
    reduced, _, _ = undetermined_directions(jacobian[:, keep], model.scale[keep], rcond)
    return Identifiability(
        tuple(model.names),
        singular,
        tuple(directions),
        {name: 0.0 for name in combinations},
        float(reduced[0] / reduced[-1]),
        combinations,
        rcond,
    )
