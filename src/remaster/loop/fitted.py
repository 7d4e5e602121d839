"""One model fitted on the optimization set (`Fitted`, `fit_blocks`): at its posterior mode, with its
pose-grouped cross-validation and the identifiability reduction of its extensions; and the
accuracy measures of its predictions (`accuracy`).

SI inside (m, rad); the JSON-ready measures are in mm where their names say so.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..inference import evidence, metrics
from ..inference.blocks import BlockModel
from ..inference.extensions import Reduction, extended_model
from ..inference.readings import Readings
from ..robot.kinematics import KinematicChain
from ..robot.priors import Priors
from ..units import MM

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
    model, reduction = extended_model(chain, data, marker, t_nr, extensions, base_held, priors)
    mode = evidence.posterior_mode(model, model.vector(start or {}))
    return Fitted(mode, reduction, evidence.cross_validate(mode, folds))
