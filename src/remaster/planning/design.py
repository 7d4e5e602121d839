"""Greedy design for workspace accuracy: which configurations to measure, in order, so that the
calibrated model's 95 % position bound across the workspace falls fastest (docs/planning.md).

The state is the linearized posterior of the complete error model (`design_posterior`): an
information matrix, from the prior (or an existing campaign's posterior). Each step scores every
remaining candidate configuration by the objective it would leave, measured with one more 3D point:
for candidate c with whitened Jacobian J_c (3, P), the rank-3 Sherman-Morrison-Woodbury form gives
at every evaluation configuration e

    C_e' = C_e - G_ec S_c^-1 G_ec^T,   G_ec = J_e Sigma J_c^T (3, 3),  S_c = I + J_c Sigma J_c^T,

so a step costs one (3E x P) (P x 3C) product instead of C inversions. The objective is the 95th
percentile (criterion 'workspace', statistic 'p95') or the mean ('mean') over the evaluation
configurations of each one's 95 % position bound; 'd-optimal' maximises log det of the information
instead (det S_c is its gain). The chosen candidate's information is added and Sigma recomputed from
the information by Cholesky, so rounding never accumulates over hundreds of steps. It stops at
`budget` configurations, or as soon as the objective is at or below `target` (m). An exchange pass
(`exchange_design`) can then swap chosen configurations for candidates while the objective falls.

The evaluation configurations are the workspace: uniform across the joint limits (`evaluation_
configurations`, a seeded Generator), as the certificate's workspace claims are made.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..inference.bounds import QUANTILE, bound_from_covariances, bound_from_moments
from ..planning import design_posterior as dp
from ..robot.kinematics import KinematicChain
from ..robot.planning import joint_range
from ..units import MM

CRITERIA = ("workspace", "d-optimal")
STATISTICS = ("p95", "mean")
EVALUATION_CONFIGURATIONS = 300
# candidate x evaluation 3x3 blocks held at once while scoring (4e6 floats, 32 MB)
SCORE_BLOCK = 4_000_000
BOUND_COLUMNS = ["n", "bound_p95_mm", "bound_mean_mm", "log_det_information"]
EXCHANGE_PASSES = 3  # passes of the exchange over the chosen configurations (it usually settles in two)
EXCHANGE_TOLERANCE = 1e-6  # relative fall of the objective a swap must give

log = logging.getLogger(__name__)


def evaluation_configurations(chain: KinematicChain, count: int, rng: np.random.Generator, within=None) -> np.ndarray:
    """(count, N) configurations uniform within the joint limits (`planning.joint_range`), or, with
    `within` (n, N) rad, within the box of its joint ranges (the candidates' domain: a campaign whose
    robot works in one region is judged there, not across limits it never goes to)."""
    ranges = np.array([joint_range(chain, j) for j in range(chain.n_joints)])
    if within is not None:
        within = np.atleast_2d(np.asarray(within, dtype=float))
        ranges = np.column_stack([within.min(axis=0), within.max(axis=0)])
    return rng.uniform(ranges[:, 0], ranges[:, 1], (count, chain.n_joints))


@dataclass(frozen=True, eq=False)
class Design:
    """A greedy design. chosen (n,): indices into the candidates, in the order chosen; bounds: one
    row per number of configurations n = 0 (prior or campaign alone) .. len(chosen): bound_p95_mm
    and bound_mean_mm (the 95th percentile and mean over the workspace of the predicted 95 %
    position bound) and log_det_information (display units); criterion, statistic; stopped: why the
    selection ended ('target', 'budget' or 'candidates')."""

    chosen: np.ndarray
    bounds: pd.DataFrame
    criterion: str
    statistic: str
    stopped: str

    @property
    def objective_column(self) -> str:
        """The bounds' column the design was chosen by (a robust design's: expected_rms_mm)."""
        return "expected_rms_mm" if self.statistic == "rms" else f"bound_{self.statistic}_mm"

    @property
    def final_bound_mm(self) -> float:
        return float(self.bounds[self.objective_column].iloc[-1])


def _summary(information: np.ndarray, eval_jacobian: np.ndarray) -> tuple[float, float, float, np.ndarray]:
    """(p95 of the bounds m, their mean m, log det information, Sigma) of a state."""
    sigma_matrix = dp.covariance(information)
    bounds = bound_from_covariances(dp.position_covariances(eval_jacobian, sigma_matrix))
    sign, logdet = np.linalg.slogdet(information)
    return float(np.quantile(bounds, QUANTILE)), float(np.mean(bounds)), float(logdet), sigma_matrix


def candidate_objectives(
    sigma_matrix: np.ndarray, candidate_jacobian: np.ndarray, eval_jacobian: np.ndarray, statistic: str = "p95"
) -> np.ndarray:
    """(C,) the objective (m) each candidate would leave, added alone to the state Sigma (P, P):
    candidate_jacobian (C, 3, P) whitened, eval_jacobian (E, 3, P) m per display unit."""
    n_eval, p = eval_jacobian.shape[0], eval_jacobian.shape[2]
    flat_eval = eval_jacobian.reshape(-1, p)
    a = flat_eval @ sigma_matrix  # (3E, P)
    base = np.einsum("eip,ejp->eij", a.reshape(n_eval, 3, p), eval_jacobian)  # (E, 3, 3)
    out = np.empty(len(candidate_jacobian))
    chunk = max(1, SCORE_BLOCK // (9 * max(n_eval, 1)))
    for begin in range(0, len(candidate_jacobian), chunk):
        jc = candidate_jacobian[begin : begin + chunk]  # (c, 3, P)
        b = np.einsum("pq,ciq->cpi", sigma_matrix, jc)  # Sigma J_c^T (c, P, 3)
        s_inv = np.linalg.inv(np.eye(3) + np.einsum("cip,cpj->cij", jc, b))
        g = (a @ jc.reshape(-1, p).T).reshape(n_eval, 3, len(jc), 3).transpose(2, 0, 1, 3)  # (c, E, 3, 3)
        reduced = base[None] - np.einsum("ceij,cjk,celk->ceil", g, s_inv, g, optimize=True)
        bounds = bound_from_moments(
            np.trace(reduced, axis1=-2, axis2=-1), np.sum(reduced * reduced, axis=(-2, -1))
        )  # (c, E)
        out[begin : begin + len(jc)] = (
            np.quantile(bounds, QUANTILE, axis=1) if statistic == "p95" else np.mean(bounds, axis=1)
        )
    return out


def log_det_gains(sigma_matrix: np.ndarray, candidate_jacobian: np.ndarray) -> np.ndarray:
    """(C,) log det(I + J_c Sigma J_c^T): the gain in log det information each candidate gives."""
    s = np.eye(3) + np.einsum("cip,pq,cjq->cij", candidate_jacobian, sigma_matrix, candidate_jacobian, optimize=True)
    return np.linalg.slogdet(s)[1]


def greedy_design(
    candidate_jacobian,
    eval_jacobian,
    prior_information,
    *,
    budget: int | None = None,
    target: float | None = None,
    criterion: str = "workspace",
    statistic: str = "p95",
) -> Design:
    """Choose candidates greedily (module docstring). candidate_jacobian (C, 3, P) whitened;
    eval_jacobian (E, 3, P) m per display unit; prior_information (P, P) the starting information;
    budget: most configurations (default: every candidate); target (m): stop once the objective
    (the statistic of the workspace bounds) is at or below it. Each choice is logged (INFO): a
    terminal running `remaster plan` shows it."""
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    if statistic not in STATISTICS:
        raise ValueError(f"statistic must be one of {STATISTICS}, got {statistic!r}")
    if budget is None and target is None:
        raise ValueError("give a budget, a target, or both")
    candidate_jacobian = np.asarray(candidate_jacobian, dtype=float)
    eval_jacobian = np.asarray(eval_jacobian, dtype=float)
    information = np.array(prior_information, dtype=float)
    limit = len(candidate_jacobian) if budget is None else min(int(budget), len(candidate_jacobian))
    remaining = np.ones(len(candidate_jacobian), dtype=bool)
    p95, mean, logdet, sigma_matrix = _summary(information, eval_jacobian)
    rows = [(0, p95 / MM, mean / MM, logdet)]
    chosen: list[int] = []
    column = 0 if statistic == "p95" else 1

    def reached() -> bool:
        return target is not None and rows[-1][1 + column] * MM <= target

    stopped = "target" if reached() else "budget"
    while not reached() and len(chosen) < limit:
        left = np.flatnonzero(remaining)
        if criterion == "workspace":
            best = left[
                int(np.argmin(candidate_objectives(sigma_matrix, candidate_jacobian[left], eval_jacobian, statistic)))
            ]
        else:
            best = left[int(np.argmax(log_det_gains(sigma_matrix, candidate_jacobian[left])))]
        remaining[best] = False
        chosen.append(int(best))
        information = information + dp.information(candidate_jacobian[best][None])
        p95, mean, logdet, sigma_matrix = _summary(information, eval_jacobian)
        rows.append((len(chosen), p95 / MM, mean / MM, logdet))
        log.info("%d of at most %d configurations chosen, p95 bound %.4g mm", len(chosen), limit, p95 / MM)
        if reached():
            stopped = "target"
    if not reached() and len(chosen) == len(candidate_jacobian) and (budget is None or budget > len(chosen)):
        stopped = "candidates"
    return Design(np.array(chosen, dtype=int), pd.DataFrame(rows, columns=BOUND_COLUMNS), criterion, statistic, stopped)


def exchange_design(
    design: Design, candidate_jacobian, eval_jacobian, prior_information, *, passes: int = EXCHANGE_PASSES
) -> Design:
    """The greedy design improved by exchange (Fedorov): each chosen configuration in turn is taken
    out and the candidate that leaves the lowest objective put in its place (itself, if none does
    better), and the passes repeat until none changes the set, at most `passes` times. Greedy
    choice is short-sighted (the first picks serve the first bound, not the final one); exchange
    keeps the number of configurations and lowers the final objective, never raises it. The bound
    table is then that of the exchanged set's prefixes in its order. Workspace criterion only."""
    if design.criterion != "workspace":
        raise ValueError("exchange improves the workspace criterion; a d-optimal design is left as chosen")
    candidate_jacobian = np.asarray(candidate_jacobian, dtype=float)
    eval_jacobian = np.asarray(eval_jacobian, dtype=float)
    prior = np.array(prior_information, dtype=float)
    chosen = [int(c) for c in design.chosen]
    column = 0 if design.statistic == "p95" else 1
    information = prior + dp.information(candidate_jacobian[chosen]) if chosen else prior
    current = _summary(information, eval_jacobian)[column]
    for _ in range(passes):
        changed = False
        for k in range(len(chosen)):
            without = information - dp.information(candidate_jacobian[[chosen[k]]])
            free = np.ones(len(candidate_jacobian), dtype=bool)
            free[chosen] = False
            free[chosen[k]] = True
            left = np.flatnonzero(free)
            scores = candidate_objectives(
                dp.covariance(without), candidate_jacobian[left], eval_jacobian, design.statistic
            )
            best = int(np.argmin(scores))
            if left[best] != chosen[k] and scores[best] < current * (1.0 - EXCHANGE_TOLERANCE):
                chosen[k] = int(left[best])
                information = without + dp.information(candidate_jacobian[[chosen[k]]])
                current = float(scores[best])
                changed = True
        if not changed:
            break
    rows = []
    information = prior.copy()
    for n in range(len(chosen) + 1):
        if n:
            information = information + dp.information(candidate_jacobian[[chosen[n - 1]]])
        p95, mean, logdet, _ = _summary(information, eval_jacobian)
        rows.append((n, p95 / MM, mean / MM, logdet))
    return Design(
        np.array(chosen, dtype=int),
        pd.DataFrame(rows, columns=BOUND_COLUMNS),
        design.criterion,
        design.statistic,
        f"{design.stopped}, then exchange",
    )


def chosen_table(candidates: pd.DataFrame, design: Design, n_joints: int) -> pd.DataFrame:
    """The chosen rows of a candidates plan table in the order chosen (the format `remaster plan`
    writes: set, pose, solution, q1..qN rad, q1_deg..qN_deg, the candidate's other columns after),
    with rank (1..n) and bound_p95_mm / bound_mean_mm: the workspace bounds once it is measured
    (with every row before it), and a robust design's expected_rms_mm."""
    table = candidates.iloc[design.chosen].reset_index(drop=True).copy()
    for j in range(n_joints):
        table[f"q{j + 1}_deg"] = np.degrees(table[f"q{j + 1}"].to_numpy(dtype=float))
    table["rank"] = np.arange(1, len(table) + 1)
    after = design.bounds.iloc[1:].reset_index(drop=True)
    table["bound_p95_mm"] = after["bound_p95_mm"].to_numpy()
    table["bound_mean_mm"] = after["bound_mean_mm"].to_numpy()
    if "expected_rms_mm" in after:
        table["expected_rms_mm"] = after["expected_rms_mm"].to_numpy()
    return table


def bound_table(design: Design) -> pd.DataFrame:
    """The bound against the number of configurations (`BOUND_COLUMNS`), with gain_mm: how much the
    objective fell with that configuration (NaN at n = 0)."""
    table = design.bounds.copy()
    table["gain_mm"] = -table[design.objective_column].diff()
    return table
