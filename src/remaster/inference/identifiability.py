"""Which parameter combinations the data cannot determine, found before any sampling.

The singular values of the identification Jacobian (d residuals / d parameters) say it: an
(almost) zero singular value is a direction along which the residuals do not change, so a flat
prior gives an improper posterior along it. remaster never reports such a direction with a
spurious small std: for each one it holds one parameter at its controller value (a zero
correction) and says so.

Which one: the zero-offset with the largest share of the null direction (the registration must
stay free to place the sensor). On the iiwa with a free six-parameter registration this is
joint 1: its offset is a rotation about the base Z axis that the registration absorbs exactly.
A marker on the last joint's axis makes that joint's offset invisible too; the analysis finds
it the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import ZeroOffsetModel

# Central differences with a 1e-6 rad/m step are exact to ~1e-10 relative, so a true null
# direction sits many decades below this, and a merely weak one (1e-4 and up) far above it.
RELATIVE_THRESHOLD = 1e-7
JACOBIAN_STEP = 1e-6


@dataclass(frozen=True)
class Identifiability:
    """names (P,): the parameters analysed; singular_values (P,) of the Jacobian (SI: m per m
    or m per rad); null_directions: one {name: component} per undetermined combination;
    held: {name: value} the parameters held to remove them; condition_number of the Jacobian
    of the parameters left free."""

    names: tuple[str, ...]
    singular_values: np.ndarray
    null_directions: tuple[dict[str, float], ...]
    held: dict[str, float]
    condition_number: float

    def report(self) -> dict:
        """A JSON-ready account of the analysis."""
        return {
            "parameters": list(self.names),
            "singular_values": self.singular_values.tolist(),
            "relative_threshold": RELATIVE_THRESHOLD,
            "null_directions": [dict(d) for d in self.null_directions],
            "held_at_controller_value": dict(self.held),
            "condition_number_free": self.condition_number,
            "note": (
                "each held parameter is not identifiable from these data: its posterior under a flat prior "
                "is improper, so it is held at the controller's value (zero correction) rather than "
                "reported with a spurious uncertainty"
            ),
        }


def null_directions(jacobian, names, threshold: float = RELATIVE_THRESHOLD):
    """Singular values (P,) and the right singular vectors whose singular value is below
    threshold x the largest, as {name: component} with components above 1e-3."""
    _, singular, vt = np.linalg.svd(jacobian, full_matrices=False)
    null = [vt[i] for i in range(len(singular)) if singular[i] < threshold * singular[0]]
    return singular, [{n: float(c) for n, c in zip(names, v) if abs(c) > 1e-3} for v in null], null


def analyse(model: ZeroOffsetModel, threshold: float = RELATIVE_THRESHOLD) -> Identifiability:
    """Analyse a model whose parameters are all free, at zero corrections."""
    theta = np.zeros(len(model.names))
    jacobian = model.jacobian(theta, JACOBIAN_STEP)
    singular, directions, vectors = null_directions(jacobian, model.names, threshold)
    held: dict[str, float] = {}
    for vector in vectors:
        weights = np.abs(vector)
        candidates = [i for i, n in enumerate(model.names) if n.startswith("zero_offsets.") and n not in held]
        if not candidates or weights[candidates].max() < 1e-3:
            candidates = [i for i, n in enumerate(model.names) if n not in held]
        held[model.names[max(candidates, key=lambda i: weights[i])]] = 0.0
    keep = [i for i, n in enumerate(model.names) if n not in held]
    reduced = np.linalg.svd(jacobian[:, keep], compute_uv=False)
    if reduced[-1] < threshold * reduced[0]:
        raise RuntimeError("holding one parameter per null direction did not make the rest identifiable")
    return Identifiability(tuple(model.names), singular, tuple(directions), held, float(reduced[0] / reduced[-1]))
