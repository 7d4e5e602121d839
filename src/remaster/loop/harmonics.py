"""Which joints and harmonic orders of the `joint_harmonics` block the data support, and each joint's
error function f_j with its 95 % band (docs/methods.md, "Joint-space harmonics").

The block adds f_j(q_j) = sum_k a_jk cos(k q_j) + b_jk sin(k q_j) to joint j's angle (rad). Once
the selection has added it, each pair (a_jk, b_jk) the data see (neither coefficient dropped by
`extensions.identifiable_extension`) is tested against 0 with the other pairs present: the chi-square
m^T C^-1 m of its posterior mean m (2,) and covariance C (2, 2) (the final fit's Laplace
approximation), 2 degrees of freedom, p = exp(-chi2 / 2). A pair is named when p is below
`level` / (number of pairs tested): Bonferroni over the pairs, so that a robot without any
cyclic error names none with probability >= 1 - level. The amplitude and phase are those of
A sin(k q + phi) = a cos(k q) + b sin(k q): A = sqrt(a^2 + b^2), phi = atan2(a, b).

Functions are given for the named joints on a grid over the joint's measured range: the posterior
mean of f_j (all its orders) and its 2.5 and 97.5 % points, from the MCMC samples when there are
some, else from the Laplace approximation (f_j is linear in the coefficients: mean +- 1.96 sd).
JSON-ready, in degrees.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd

from ..inference.evidence import PosteriorMode
from ..inference.extensions import Reduction

BLOCK = "joint_harmonics"
GRID = 61  # angles across a joint's measured range at which f_j and its band are given
Z95 = 1.959963984540054  # two-sided 95 % point of the normal
_NAME = re.compile(rf"^{BLOCK}\.q(\d+)\.(cos|sin)(\d+)$")


def pairs(names) -> dict[tuple[int, int], tuple[str, str]]:
    """{(joint 1-based, order): (cos name, sin name)} of the block's parameters among `names`."""
    found: dict[tuple[int, int], dict[str, str]] = {}
    for name in names:
        match = _NAME.match(name)
        if match:
            found.setdefault((int(match[1]), int(match[3])), {})[match[2]] = name
    return {key: (v["cos"], v["sin"]) for key, v in sorted(found.items()) if len(v) == 2}


def function_matrix(q: np.ndarray, orders) -> np.ndarray:
    """(n, 2 K) regressors [cos k q, sin k q] per order k of `orders`, for angles q (n,) rad."""
    q = np.asarray(q, dtype=float)[:, None]
    return np.concatenate([np.column_stack([np.cos(k * q[:, 0]), np.sin(k * q[:, 0])]) for k in orders], axis=1)


def harmonics_report(
    mode: PosteriorMode, reduction: Reduction, q: np.ndarray, level: float, samples: pd.DataFrame | None = None
) -> dict:
    """The named joints and orders and their functions (module docstring): mode: the final fit,
    which has the block; reduction: its identifiability; q (n, N) rad: the optimization readings
    (the measured ranges); level: the family-wise level; samples: MCMC samples (columns = the free
    parameters' names, SI), None for the Laplace band."""
    names = list(mode.model.names)
    index = {n: i for i, n in enumerate(names)}
    theta, covariance = mode.theta, mode.covariance[:-1, :-1]
    found = pairs(names)
    seen = {key: not (cos in reduction.dropped and sin in reduction.dropped) for key, (cos, sin) in found.items()}
    tested = sum(seen.values())
    threshold = level / max(tested, 1)
    rows = []
    for (joint, order), (cos, sin) in found.items():
        at = [index[cos], index[sin]]
        mean, cov = theta[at], covariance[np.ix_(at, at)]
        chi2 = float(mean @ np.linalg.solve(cov, mean))
        amplitude = float(np.hypot(*mean))
        gradient = mean / amplitude if amplitude > 0 else np.zeros(2)
        p_value = math.exp(-0.5 * chi2)
        rows.append(
            {
                "joint": f"q{joint}",
                "order": order,
                "cos_deg": math.degrees(mean[0]),
                "sin_deg": math.degrees(mean[1]),
                "amplitude_deg": math.degrees(amplitude),
                "amplitude_std_deg": math.degrees(math.sqrt(max(gradient @ cov @ gradient, 0.0))),
                "phase_deg": math.degrees(math.atan2(mean[0], mean[1])),
                "chi2": chi2,
                "p_value": p_value,
                "seen_by_data": seen[(joint, order)],
                "named": bool(seen[(joint, order)] and p_value < threshold),
            }
        )
    named: dict[str, list[int]] = {}
    for row in rows:
        if row["named"]:
            named.setdefault(row["joint"], []).append(row["order"])
    functions = {}
    for joint in named:
        j = int(joint[1:])
        orders = sorted(k for (jj, k) in found if jj == j)
        columns = [index[name] for k in orders for name in found[(j, k)]]
        grid = np.linspace(q[:, j - 1].min(), q[:, j - 1].max(), GRID)
        basis = function_matrix(grid, orders)  # (GRID, 2 K)
        mean = basis @ theta[columns]
        if samples is not None and len(samples):
            draws = samples[[names[c] for c in columns]].to_numpy(float) @ basis.T  # (m, GRID)
            low, high, source = np.quantile(draws, 0.025, axis=0), np.quantile(draws, 0.975, axis=0), "mcmc"
            mean = draws.mean(axis=0)
        else:
            sd = np.sqrt(np.einsum("gi,ij,gj->g", basis, covariance[np.ix_(columns, columns)], basis))
            low, high, source = mean - Z95 * sd, mean + Z95 * sd, "laplace"
        functions[joint] = {
            "angle_deg": np.degrees(grid).tolist(),
            "mean_deg": np.degrees(mean).tolist(),
            "q2.5_deg": np.degrees(low).tolist(),
            "q97.5_deg": np.degrees(high).tolist(),
            "band_from": source,
        }
    return {
        "orders": max((k for _, k in found), default=0),
        "level": level,
        "pairs_tested": tested,
        "p_threshold": threshold,
        "rule": "a (joint, order) is named when the chi-square (2 dof) of its posterior (cos, sin) coefficients "
        "against 0, with every other term present (Laplace covariance of the final fit), has p below "
        "level / pairs_tested (Bonferroni); amplitude and phase of A sin(k q + phase)",
        "terms": rows,
        "named": named,
        "named_joints": list(named),
        "functions": functions,
    }


def evaluate(function: dict, angles_deg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, q2.5, q97.5) deg of one reported f_j at angles (deg) inside its grid (linear
    interpolation of the reported grid)."""
    grid = np.asarray(function["angle_deg"])
    return tuple(np.interp(angles_deg, grid, np.asarray(function[k])) for k in ("mean_deg", "q2.5_deg", "q97.5_deg"))
