"""Is the loop closed? What is left against what the sensor's noise and the robot's repeatability explain.

The noise floor (m, per axis) is what no model of the robot can remove: the sensor's stated noise
(campaign.yaml `noise`), the instrument's own per-point std where the table carries it (`std` or
`std_x/y/z`, their RMS per axis) and, where the campaign measures one configuration more than once,
the spread of those repeats (sensor noise and the robot's repeatability together; pooled within-
configuration standard deviation per axis). It is the largest of those that are known. A noise
model fitted to the residuals (a tracker's range/transverse shape) is not the floor: its std is
compared with the floor, and one well above it is model error the noise model took up (a range std
above NOISE_MODEL_RATIO times the floor: the shape is not kept, `tracker_noise.choose_noise`).

After each round of the loop the residual is measured by its pose-grouped cross-validated RMS per
axis on the optimization set (held-out poses: an in-sample residual would flatter a larger
model). A correct model does not reach the floor there: a fit without a fold errs at the fold's
rows by its parameters' spread as well as by the noise, by a factor its Jacobian gives
(`evidence.CrossValidation.noise_inflation`: 1.55 in mean square on the 25-configuration
campaign of tests/loop/test_noise_floor.py); the held-out floor is the floor times the root of that
factor. The closure is a test at a stated level (`loop_closure/closure_level`): a correct model's
pooled held-out sum of squares over the floor's variance is a weighted sum of chi-square variables
whose first three cumulants the folds' Jacobians give (`evidence.held_out_cumulants`), taken as a
shifted, scaled chi-square with the same three (Pearson's approximation, `chi_square.pearson_sf`). Few rows per
parameter make a few large weights and a long tail (at 25 configurations the level lies at 1.3-2.6 x
the held-out floor); many rows make it narrow (at 17,500 rows, 1.007 x), so that a fixed ratio
would call correct small campaigns not closed and a large campaign's model error closed. The loop is
closed when the probability of a held-out error at least as large under a correct model is at least
the level; otherwise the structured residual left per axis is sqrt((RMS^2 - held-out floor^2) / c),
c = held-out floor^2 / floor^2 the folds' inflation. A structured residual s per number that a fit
cannot follow is held out as the noise is: a fold's fit errs at the fold's rows by what the other
rows' s and noise push its parameters by, so the held-out mean square is c (floor^2 + s^2) and the
excess over the held-out floor is c s^2, not s^2. What a fit of every row leaves at commands near
the data beyond the noise is s (taken per axis and command as independent, as the declared model
error is drawn): on 25 configurations c is 1.55 (tests/loop/test_noise_floor.py) to 7 (joint 3
held, link geometry traded with the zero-offsets), so the excess's root would declare up to 2.7 s;
at many rows c is about 1 and the two agree. Where the folds' spread is
not known (the residual GP's folds) the weights are taken as 1: the plain floor, which never
flatters a fit. Each step's share is
the part of the structured residual (mean square above the floor) it removed: an effect that removes
a small share is not what the residual was.

The floor is taken as known: a stated noise that understates the instrument's calls a correct model
not closed, and its structured residual is then what the statement missed.

SI inside (m); the report's numbers are in mm.
"""

from __future__ import annotations

import math

import numpy as np

from ..inference import chi_square
from ..units import MM

# a fitted noise model (a tracker's range/transverse shape) whose std is this many times the floor took
# up model error: a noise std is estimated from every row, so a fifth above the floor is not its spread
NOISE_MODEL_RATIO = 1.2
MAIN_CAUSE_SHARE = 0.5  # an effect that removes less than this share of the structured residual is not "the cause"
SAME_READING = 1e-9  # rad: rows whose readings agree to this are one configuration measured again


def configuration_groups(q) -> tuple[np.ndarray, np.ndarray]:
    """(group (n,), counts (G,)): rows of readings q (n, N) that agree to SAME_READING share a
    group, one configuration measured counts[group] times."""
    _, group, counts = np.unique(
        np.round(np.asarray(q, dtype=float) / SAME_READING), axis=0, return_inverse=True, return_counts=True
    )
    return group.ravel(), counts


def repeatability(q, measured) -> tuple[float | None, int]:
    """Pooled within-configuration std per axis (m) of measured positions (n, 3) at readings
    q (n, N), and how many configurations were repeated; (None, 0) without repeats."""
    measured = np.asarray(measured, dtype=float)
    group, counts = configuration_groups(q)
    repeated = counts[group] > 1
    if not repeated.any():
        return None, 0
    g, x = group[repeated], measured[repeated]
    sums = np.zeros((counts.size, 3))
    np.add.at(sums, g, x)
    centred = x - (sums / counts[:, None])[g]
    dof = 3 * (int(repeated.sum()) - int(np.sum(counts > 1)))
    return math.sqrt(float(np.sum(centred**2)) / dof), int(np.sum(counts > 1))


def noise_floor(stated: float | None, repeats: float | None, measured: float | None = None) -> float | None:
    """The largest of the stated noise, the repeats' spread and the instrument's own per-point std
    (the RMS per axis of the campaign's `std` columns) that are known (m), else None."""
    known = [v for v in (stated, repeats, measured) if v is not None]
    return max(known) if known else None


def floor_of(q, measured, stated: float | None, point_std=None) -> tuple[float | None, float | None, int]:
    """The noise floor (m per axis) of readings q (n, N) and their measured positions (n, 3): the
    stated noise, their repeats' spread and the instrument's per-point std (n, 3) or None; with the
    repeats' spread and how many configurations were repeated."""
    repeats, repeated = repeatability(q, measured)
    return noise_floor(stated, repeats, point_std_rms(point_std)), repeats, repeated


def point_std_rms(point_std) -> float | None:
    """RMS per axis (m) of the instrument's per-point std (n, 3), None without them."""
    return None if point_std is None else math.sqrt(float(np.mean(np.asarray(point_std, dtype=float) ** 2)))


def range_transverse_rms(sigma_range: float, growth_per_m: float, measured) -> float:
    """The noise's RMS per axis (m) a range/transverse model (`remaster.noise`) of range std
    sigma_range (m) and growth g (1/m) implies at measured points (n, 3) m in the tracker's frame:
    sigma sqrt(mean((1 + 2 k_i^2) / 3)), k_i^2 = 1 + (g d_i)^2 (one range and two transverse axes)."""
    distance = np.linalg.norm(np.asarray(measured, dtype=float), axis=-1)
    k2 = 1.0 + (growth_per_m * distance) ** 2
    return float(sigma_range * math.sqrt(float(np.mean((1.0 + 2.0 * k2) / 3.0))))


def verdict(rms_per_axis: float, floor: float | None, level: float, numbers: int, cumulants=None) -> dict:
    """Closed or not at `level`, the structured residual left per axis (mm) and the sentence the
    report shows; rms_per_axis over `numbers` held-out numbers (3 per point), cumulants: a correct
    model's held-out sum of squares over the noise variance (`evidence.CrossValidation.null_cumulants`;
    None: the plain floor's, chi-square with `numbers` degrees of freedom). Module docstring."""
    if floor is None:
        return {
            "closed": None,
            "structured_mm": None,
            "rms_per_axis_mm": rms_per_axis / MM,
            "text": "unknown: the campaign states no sensor noise and repeats no configuration",
        }
    cumulants = chi_square.cumulants(numbers) if cumulants is None else tuple(float(c) for c in cumulants)
    inflation = max(cumulants[0] / numbers, 1.0)
    held_out_floor = floor * math.sqrt(inflation)
    p_value = chi_square.pearson_sf(numbers * (rms_per_axis / floor) ** 2, cumulants)
    closed = p_value >= level
    # the held-out excess is inflated by the folds' parameter spread as the noise is: a fit of every
    # row errs by the structured part alone (module docstring)
    structured = math.sqrt(max(rms_per_axis**2 - held_out_floor**2, 0.0) / inflation)
    ratio = rms_per_axis / held_out_floor
    text = (
        f"closed: the residual is at the sensor's noise ({ratio:.2f} x the noise floor held out, p = {p_value:.2g})"
        if closed
        else f"not closed: {structured / MM:.3g} mm of structured residual left per axis "
        f"({ratio:.2f} x the noise floor held out, p = {p_value:.2g} at level {level:g})"
    )
    return {
        "closed": bool(closed),
        "structured_mm": structured / MM,
        "rms_per_axis_mm": rms_per_axis / MM,
        "held_out_floor_mm": held_out_floor / MM,
        "ratio_to_floor": ratio,
        # the ratio up to which this many held-out numbers would be found closed at the level
        "closed_up_to_ratio": math.sqrt(chi_square.pearson_isf(level, cumulants) / numbers) * floor / held_out_floor,
        "p_value": p_value,
        "level": level,
        "held_out_numbers": int(numbers),
        "text": text,
    }


def share(before: float, after: float, before_verdict: dict) -> float | None:
    """The share of the structured residual (mean square per axis above the held-out floor of the
    model before the step: `verdict`) a step removed; before and after are RMS per axis (m). None
    when the loop was already closed before the step (no structured residual was left to share)."""
    if before_verdict.get("closed"):
        return None
    floor = (before_verdict.get("held_out_floor_mm") or 0.0) * MM
    excess = before**2 - floor**2
    return float((before**2 - after**2) / excess)
