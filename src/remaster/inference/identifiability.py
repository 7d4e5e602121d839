"""Which parameter combinations the data cannot determine, found before any sampling.

The singular values of the identification Jacobian (d residuals / d parameters) say it: an
(almost) zero singular value is a direction along which the residuals do not change, so a flat
prior gives an improper posterior along it. remaster never reports such a direction with a
spurious small std: for each one it holds one parameter at its controller value (a zero
correction) and says so.

The test is the one `least_squares.least_squares_laplace` applies to the fit that follows, and it
lives here (`undetermined_directions`, imported by `least_squares`): singular values of the Jacobian
in step units (J * scale: mm and deg, so that the test does not depend on metres against
radians) below RCOND times the largest. Holding by a different test would leave combinations between the two tests
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

A zero-offset the data see only at the noise level is held the same way (`loose_zero_offsets`):
given the fit's sigma, its Laplace std sigma sqrt((J^T J)^-1) over STD_BOUND (0.5 deg, the
controller marks' tolerance) says nothing the marks do not. `fit.identified` runs both tests at
the least-squares optimum the Laplace fit then starts from and tests at (docs/methods.md,
"Identifiability: joint 1"); with no sigma (`analyse` alone, e.g. a design before any data) only
the singular values decide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .model import display_unit

# A singular value of the Jacobian in step units (J * scale: mm and deg) below RCOND x the largest
# is an undetermined combination: its variance would be 1e12 times the best-determined one's.
# `least_squares.least_squares_laplace` refuses it and `analyse` holds it, by the same test
# (`undetermined_directions`), so that no combination is left between the two.
RCOND = 1e-6

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
# A zero-offset the data determine no better than this (Laplace std at the fit's sigma, rad) is
# held like one they cannot see: the controller's marks (Vernier scales) already place a joint to
# about this much (the priors' held_zero_offset_deg, 0.5 deg for every class of arm), so an
# estimate this loose says nothing the marks do not, and a correction from it could be worse
# than none. A marker a few mm off the last joint's axis leaves that joint's offset so.
STD_BOUND = math.radians(0.5)
STD_BOUND_PREFIX = "zero_offsets."  # the bound is a joint's: a registration has no marks


def undetermined_directions(jacobian, scale, rcond: float = RCOND) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit-free identifiability test: (singular values (P,) of J * scale, largest first;
    V^T (P, P) in step units; small (P,) bool, the singular values below rcond x the largest).
    jacobian (k, P) SI; scale (P,) SI size of one step unit. A Jacobian without any non-zero
    entry has every direction undetermined."""
    j = np.asarray(jacobian, dtype=float) * np.asarray(scale, dtype=float)
    _, singular, vt = np.linalg.svd(j, full_matrices=False)
    small = singular < rcond * singular[0] if singular.size and singular[0] > 0 else np.ones(singular.size, bool)
    return singular, vt, small


@dataclass(frozen=True)
class Identifiability:
    """names (P,): the parameters analysed; singular_values (P,) of the Jacobian in step units
    (J * scale: per mm or per deg), largest first; null_directions: one {name: component} per
    undetermined combination (step units, largest component +-1); held: {name: value} the
    parameters held to remove them and the zero-offsets the data determine no better than
    std_bound; combinations: {held name: {name: weight}}, the combination each held parameter
    stood for (step units, its own weight 1: one mm or deg of it is undone, or for a loose one
    nearly undone, by `weight` mm or deg of each other); condition_number of the step-unit
    Jacobian of the parameters left free; rcond: the singular-value test's threshold; loose:
    {held name: its Laplace std (rad) at sigma} of the zero-offsets held by the std test; sigma
    (m): the fit's noise the std test took (None: that test not applied); std_bound (rad)."""

    names: tuple[str, ...]
    singular_values: np.ndarray
    null_directions: tuple[dict[str, float], ...]
    held: dict[str, float]
    condition_number: float
    combinations: dict[str, dict[str, float]]
    rcond: float = RELATIVE_THRESHOLD
    loose: dict[str, float] = field(default_factory=dict)
    sigma: float | None = None
    std_bound: float = STD_BOUND

    def reasons(self) -> dict[str, str]:
        """{held name: why, in a few words}: 'not identifiable' (a singular value below rcond x the
        largest) or 'not determined' (a std wider than the controller's marks)."""
        return {
            name: (
                f"not determined: std {math.degrees(self.loose[name]):.3g} deg > {math.degrees(self.std_bound):g} deg"
                if name in self.loose
                else "not identifiable"
            )
            for name in self.combinations
        }

    def statements(self) -> list[str]:
        """One plain sentence per held parameter: what the data cannot tell apart."""
        out = []
        for name, combination in self.combinations.items():
            others = [f"{w:+.3g} {display_unit(n)} of {n}" for n, w in combination.items() if n != name]
            if name in self.loose:
                undone = ("; 1 deg of it is nearly undone by " + ", ".join(others)) if others else ""
                out.append(
                    f"{name} is held at the controller's value: the data determine it only to "
                    f"{math.degrees(self.loose[name]):.3g} deg (1 std at sigma {self.sigma * 1e3:.3g} mm), no "
                    f"better than the controller's marks ({math.degrees(self.std_bound):g} deg){undone}"
                )
                continue
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
            "held_reasons": self.reasons(),
            "held_combinations": {name: dict(c) for name, c in self.combinations.items()},
            "not_determined_std_deg": {name: math.degrees(v) for name, v in self.loose.items()},
            "std_bound_deg": math.degrees(self.std_bound),
            "sigma_m": self.sigma,
            "statements": self.statements(),
            "condition_number_free": self.condition_number,
            "note": (
                "each held parameter is not identifiable from these data (its posterior under a flat prior "
                "is improper) or, a zero-offset, not determined (its Laplace std at the fit's sigma wider than "
                "std_bound_deg, the controller marks' tolerance): it is held at the controller's value (zero "
                "correction) rather than reported with a spurious or useless uncertainty; the tests are the "
                "Laplace fit's (singular values of the Jacobian in step units below relative_threshold x the "
                "largest; its covariance at its optimum)"
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


def loose_zero_offsets(jacobian, names, scale, sigma: float, bound: float = STD_BOUND) -> dict[str, tuple]:
    """{held name: (its combination, its std (rad))} of the zero-offsets the data determine no
    better than `bound`: the Laplace covariance sigma^2 (J^T J)^-1 of the parameters (the
    fit's own formula), the zero-offset with the widest std over `bound` held, the covariance of
    the rest taken again without it (holding one narrows the others it was confounded with), until
    every free zero-offset is within the bound. jacobian (k, P) SI of identifiable parameters
    `names`, scale (P,) step units, sigma (m) the fit's noise. The combination: the posterior's
    regression on the held parameter (step units, its own weight 1), the direction the data leave
    loosest along it."""
    jacobian = np.asarray(jacobian, dtype=float)
    scale = np.asarray(scale, dtype=float)
    names = list(names)
    out: dict[str, tuple] = {}
    free = list(range(len(names)))
    while free:
        singular, vt, _ = undetermined_directions(jacobian[:, free], scale[free])
        inverse = (vt.T / singular**2) @ vt  # (J_s^T J_s)^-1, step units
        std = sigma * np.sqrt(np.diag(inverse)) * scale[free]
        excess = np.array([s / bound if names[i].startswith(STD_BOUND_PREFIX) else 0.0 for i, s in zip(free, std)])
        k = int(np.argmax(excess))
        if excess[k] <= 1.0:
            break
        regression = inverse[:, k] / inverse[k, k]
        top = np.max(np.abs(regression))
        combination = {names[i]: float(w) for i, w in zip(free, regression) if abs(w) >= PART * top}
        out[names[free[k]]] = (combination, float(std[k]))
        del free[k]
    return out


class LinearisedModel(Protocol):
    """What the analysis needs of a model (a `blocks.BlockModel`, which imports this module's
    JACOBIAN_STEP): its parameter names and scales, and its Jacobian at theta."""

    names: list[str]
    scale: np.ndarray

    def weighted_jacobian(self, theta: np.ndarray, step: float) -> np.ndarray: ...


def analyse(model: LinearisedModel, rcond: float = RELATIVE_THRESHOLD, theta=None, sigma: float | None = None):
    """Analyse a model whose parameters are all free, at theta (P,) (default zero corrections):
    the singular-value test (`hold_undetermined`), then, given the fit's noise sigma (m), the std
    test on what it leaves free (`loose_zero_offsets`, bound STD_BOUND). Returns `Identifiability`."""
    theta = np.zeros(len(model.names)) if theta is None else np.asarray(theta, dtype=float)
    jacobian = model.weighted_jacobian(theta, JACOBIAN_STEP)  # a full-pose probe's orientations included
    singular, _, _ = undetermined_directions(jacobian, model.scale, rcond)
    combinations, directions = hold_undetermined(jacobian, model.names, model.scale, rcond)
    loose = {}
    if sigma is not None:
        keep = [i for i, n in enumerate(model.names) if n not in combinations]
        found = loose_zero_offsets(jacobian[:, keep], [model.names[i] for i in keep], model.scale[keep], sigma)
        combinations.update({name: combination for name, (combination, _) in found.items()})
        loose = {name: std for name, (_, std) in found.items()}
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
        loose,
        None if sigma is None else float(sigma),
    )
