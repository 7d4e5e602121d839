"""The link geometry's prior scale chosen by its evidence (type-II maximum likelihood on the
optimization set), among a few widenings of the configured priors.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..inference import evidence
from ..inference.extensions import extended_model
from ..inference.readings import Readings
from ..robot.priors import Priors

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
            model, _ = extended_model(
                chain, data, marker, t_nr, ("link_geometry", "marker_offset"), base_held, scaled_priors(priors, scale)
            )
            evidence_at[scale] = float(evidence.posterior_mode(model).log_evidence)
        except np.linalg.LinAlgError:  # too few data for the model (the selection says so in its own words)
            return 1.0, {}
    return max(evidence_at, key=evidence_at.get), {f"x{k:g}": v for k, v in evidence_at.items()}
