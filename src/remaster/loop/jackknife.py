"""The between-design component of the zero-offsets: how far a model's zero-offsets move with the
choice of poses measured, estimated from the data by a delete-a-group jackknife over poses.

The posterior std of a zero-offset says how well these data fix it if the model's residual were
independent noise; what the model still lacks makes the estimate depend on which poses were
measured, so that two campaigns of one arm differ by more than either posterior allows. The
jackknife sees that: the model is refitted at its posterior mode (from the full fit's mode, same
blocks, held parameters, priors and noise shape) leaving out one group of whole poses at a time, the
groups contiguous in time (`held_out.TimeBlocked`: the time column, or the row order as the
measurement order; K = loop_closure/jackknife_groups), so that each refit sees a design that lacks a
whole stretch of the campaign rather than a thinned copy of the same design (groups of poses
assigned in turn measure resampling noise and add nothing on dense designs), and the spread of
the K estimates gives u_J (`uncertainty.jackknife_variance`); a group whose refit departs (its
error on the rows it left out above `evidence.DEPARTED_RATIO` times the fit's sigma) is left out
of it and named (`departed_groups_warning`). The component beyond
the posterior's own std is u_between = sqrt(max(u_J^2 - u_p^2, 0)), u_p the Laplace std of the full
fit (`uncertainty.between_design`). The residual GP, when added, is not refitted: it is the
parametric model's zero-offsets that are certified.

SI inside (rad); the report is JSON-ready in degrees where its keys say so.
"""

from __future__ import annotations

import numpy as np

from ..inference import evidence
from ..inference.uncertainty import between_design, jackknife_variance
from ..units import DEG
from .fitted import Fitted
from .held_out import TimeBlocked

ZERO_OFFSET_PREFIX = "zero_offsets."
MIN_GROUPS = 3  # two groups give a spread of one difference: no estimate of a variance worth the name
TOO_FEW = "not computed: too few data: without one group of poses the rest do not determine the model's parameters"


def too_few_warning(between: dict, rows: int, poses: int, kept: bool) -> str | None:
    """The loop report's warning when a jackknife of `between` ({model: `zero_offset_jackknife`})
    found the data too few (`rows` measured optimization configurations in `poses` poses), or None;
    `kept`: the selection added no effect (the zero-offset model is the loop's)."""
    models = [name for name, result in between.items() if result["method"] == TOO_FEW]
    if not models:
        return None
    return (
        f"too few data for the candidates: the optimization set's {rows} measured configurations in {poses} poses "
        f"do not determine the {' and '.join(models)} model{'s' if len(models) > 1 else ''} once a group of poses is "
        "left out; the cross-validated scores (each candidate's and the closure test's) rest on such fits, and the "
        "between-design component of the zero-offsets is not computed (their uncertainty is the posterior's alone)"
        + ("; the zero-offset model is kept" if kept else "")
        + ": measure more poses"
    )


def leave_group_out(fitted: Fitted, folds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((K, P) the model's mode refitted without each fold of folds (n,) in turn (sorted fold
    labels), from the full fit's mode; (K,) each refit's RMS per axis (m) on the fold it left out)."""
    data = fitted.model.data
    estimates, held_out = [], []
    for fold in np.unique(folds):
        model = fitted.model.on(data.subset(folds != fold))
        theta = evidence.posterior_mode(model, fitted.theta).theta
        residuals = fitted.model.on(data.subset(folds == fold)).residuals(theta)
        estimates.append(theta)
        held_out.append(float(np.sqrt(np.mean(residuals**2))))
    return np.array(estimates), np.array(held_out)


def departed_groups_warning(between: dict) -> str | None:
    """The loop report's warning when a jackknife of `between` ({model: `zero_offset_jackknife`})
    left out groups whose refit departed, or None."""
    named = [
        f"{model}: group{'s' if len(r['departed_groups']) > 1 else ''} {', '.join(map(str, r['departed_groups']))}"
        for model, r in between.items()
        if r.get("departed_groups")
    ]
    if not named:
        return None
    return (
        "jackknife groups whose refit departed (its error on the group it left out above "
        f"{evidence.DEPARTED_RATIO:g} x the fit's sigma per axis: the rest leave a combination almost free without "
        f"them): {'; '.join(named)}; each was left out of u_between, the others give it"
    )


def zero_offset_jackknife(fitted: Fitted, poses, groups: int) -> dict:
    """The between-design component of the model's free zero-offsets (module docstring) over
    `groups` pose-grouped folds of its optimization readings (one pose per group when there are
    fewer poses; not computed below MIN_GROUPS); poses (n,) their pose labels.
    JSON-ready: groups, method, and per zero-offset parameter posterior_std_deg (Laplace),
    jackknife_std_deg, u_between_deg, dof (of the combined u, `uncertainty.between_design`) and
    the K estimates_deg."""
    groups = min(groups, len(np.unique(poses)))  # a campaign of fewer poses: one pose per group
    if groups < MIN_GROUPS:
        return {"groups": groups, "method": f"not computed: fewer than {MIN_GROUPS} poses", "parameters": {}}
    in_time = TimeBlocked.of(fitted.model.data, poses, groups)
    folds = in_time.folds if in_time else evidence.pose_folds(poses, groups)
    try:
        estimates, held_out = leave_group_out(fitted, folds)
    except np.linalg.LinAlgError:
        # a small optimization set (the reader's minimum is just enough for the full fit) leaves
        # some parameter undetermined once a group of poses is out: no spread to estimate, and the
        # report says so rather than the loop closure ending in a traceback
        return {"groups": groups, "method": TOO_FEW, "parameters": {}}
    # a group whose refit departs (the others leave a combination almost free) measures that
    # combination, not the design: left out, named, as the cross-validation's departed folds are
    departed = held_out > evidence.DEPARTED_RATIO * fitted.mode.sigma
    if np.count_nonzero(~departed) < MIN_GROUPS:
        return {
            "groups": groups,
            "method": TOO_FEW,
            "parameters": {},
            "departed_groups": np.flatnonzero(departed).tolist(),
        }
    estimates = estimates[~departed]
    groups = len(estimates)
    u_jackknife = np.sqrt(jackknife_variance(estimates))
    u_posterior = fitted.mode.std
    u_between, dof = between_design(u_posterior, u_jackknife, groups)
    out = {}
    for i, name in enumerate(fitted.model.names):
        if name.startswith(ZERO_OFFSET_PREFIX):
            out[name] = {
                "posterior_std_deg": float(u_posterior[i] / DEG),
                "jackknife_std_deg": float(u_jackknife[i] / DEG),
                "u_between_deg": float(u_between[i] / DEG),
                "dof": float(dof[i]) if np.isfinite(dof[i]) else None,  # None: infinite
                "estimates_deg": (estimates[:, i] / DEG).tolist(),
            }
    return {
        "groups": groups,
        "departed_groups": np.flatnonzero(departed).tolist(),
        "method": "delete-a-group jackknife over groups of whole poses contiguous in time ("
        + (in_time.order if in_time else "poses in turn")
        + "), the mode refitted without each; u_between = sqrt(max(u_jackknife^2 - u_posterior^2, 0))",
        "parameters": out,
    }
