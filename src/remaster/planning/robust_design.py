"""Designs robust to what the error model lacks: the expected error of the calibrated model across the
workspace when the arm has a discrepancy the model cannot take (docs/planning.md, "robust").

The workspace criterion (`design`) scores a design by the posterior of the error model as if the
model were true. No model of a real arm is: after the complete error model, a UR5's residual is
twice its tracker's noise (docs/planning.md). A design that concentrates its measurements where the
parameters are best determined then fits the discrepancy found there into the parameters, and the
calibration is biased everywhere else: on the real UR5 grid, rows chosen by it calibrate worse than as
many random rows (benchmarks/results/planner.md). This module scores a design by what
it would leave *with* the discrepancy.

The measured positions are  y = J theta + delta(q) + e,  e ~ N(0, sigma^2 I) the sensor, theta ~
N(0, P) the error model's parameters under their prior, and delta a Gaussian process on the joint
angles with the residual GP's kernel (`remaster.inference.gp.kernels.kernel`: k(q, q') I3, the same on the three
axes), independent of theta and e. The calibration is the model's MAP, which ignores delta:

    theta_hat = Sigma Jw^T y / sigma,   Sigma = (Jw^T Jw + P^-1)^-1,   Jw = J / sigma (whitened).

Its error at a workspace configuration q_e, J_e theta_hat - (J_e theta + delta_e), has mean zero and
the covariance

    C_e = J_e Sigma J_e^T                                    (the posterior: prior and noise)
        + J_e Sigma Jw^T (K_DD / sigma^2) Jw Sigma J_e^T     (the discrepancy fitted into theta)
        - J_e Sigma Jw^T K_De / sigma - (...)^T              (... where it is correlated with q_e)
        + K_ee                                               (the discrepancy the model cannot take).

The criterion is the mean over the workspace configurations of tr C_e, the expected squared error of
the calibrated model there (the integrated mean squared error of Box and Draper's designs under
model bias), reported as the RMS per axis sqrt(mean tr C_e / 3). Summed over e, with G = sum_e
J_e^T J_e, B = Jw^T K_DD Jw / sigma^2 and H = sum_{i in design} Jw_i^T h_i, h_i = sum_e k(q_i, q_e)
J_e / sigma:

    sum_e tr C_e = tr(Sigma G) + tr(Sigma B Sigma G) - 2 tr(Sigma H) + 3 sum_e k(q_e, q_e).

A candidate c adds a rank-3 step to the information and, to B and H, its own terms and its kernel
with the configurations already chosen (U_c = sum_i k(q_i, q_c) Jw_i / sigma^2); every candidate's
score is then a few (P, 3) and (3, 3) products (`_scores`), and the greedy choice costs about what
the workspace criterion's does. With no discrepancy (signal 0) the criterion is the posterior's mean
squared error alone; with one, a measurement repeated at the same configuration buys nothing against
the discrepancy there, and a design spread like the workspace averages it out instead of fitting it.

The discrepancy's prior (`workspace_discrepancy`): a signal std per axis (by default the sensor's
noise: the smallest a loop that has not closed leaves) and per-joint lengthscales (by default each
joint's range over the workspace: the residual GP's own prior centre, "it varies about once over
what is measured"); or the residual GP a campaign's loop closure fitted (`discrepancy_of`).

SI inside (m, rad); the parameters in the error model's display units (`design_posterior`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..inference.gp.kernels import LENGTH_BOUNDS, Hyperparameters, kernel
from ..planning import design_posterior as dp
from ..units import MM

CRITERION = "robust"  # `remaster plan --criterion robust`
# candidates scored at once: bounds the (c, P, 3) work arrays
SCORE_CHUNK = 2048
# a campaign's measured rows the discrepancy sums take: their kernel is (3M)^2 (3000 rows: 650 MB)
MAX_MEASURED_ROWS = 3000

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Discrepancy:
    """A Gaussian-process discrepancy on the joint angles: lengthscales (N,) rad (inf: a joint it
    does not depend on), signal_std (m per axis)."""

    lengthscales: np.ndarray
    signal_std: float

    def kernel(self, qa, qb) -> np.ndarray:
        """k(qa_i, qb_k) (na, nb) m^2 of configurations qa (na, N) and qb (nb, N) rad."""
        lengthscales = np.asarray(self.lengthscales, dtype=float)
        if self.signal_std == 0.0 or not np.isfinite(lengthscales).any():
            # a discrepancy that depends on no joint is one constant offset: k = s^2 between any two
            return np.full((len(np.atleast_2d(qa)), len(np.atleast_2d(qb))), self.signal_std**2)
        return kernel(np.atleast_2d(qa), np.atleast_2d(qb), Hyperparameters(lengthscales, self.signal_std, 0.0))

    def report(self) -> dict:
        return {
            "signal_std_mm": self.signal_std / MM,
            "lengthscales_deg": [None if not np.isfinite(v) else float(np.degrees(v)) for v in self.lengthscales],
        }


def workspace_discrepancy(q_workspace, signal_std: float) -> Discrepancy:
    """The default prior: `signal_std` (m per axis), each joint's lengthscale its range (rad) over the
    workspace configurations q_workspace (E, N), clipped to the residual GP's bounds; a joint the
    workspace never turns gets none (inf)."""
    if not signal_std >= 0.0:
        raise ValueError(f"the discrepancy's signal std must be >= 0 m, got {signal_std!r}")
    ranges = np.ptp(np.atleast_2d(np.asarray(q_workspace, dtype=float)), axis=0)
    lengthscales = np.where(ranges > 0.0, np.clip(ranges, *LENGTH_BOUNDS), np.inf)
    return Discrepancy(lengthscales, float(signal_std))


def discrepancy_of(hyperparameters: dict, q_workspace=None) -> Discrepancy:
    """The discrepancy a campaign's residual GP measured: its hyperparameters as loop_closure.json
    writes them (`Hyperparameters.report`: lengthscales_rad with null for a joint not turned,
    signal_std_m). A joint the campaign never turned has no lengthscale, which would make the
    discrepancy constant along exactly the joint the next measurements may move: with q_workspace
    (E, N) rad it gets the default's instead (its range over the workspace)."""
    hyper = Hyperparameters.from_report(hyperparameters)
    lengthscales = hyper.lengthscales
    if q_workspace is not None:
        default = workspace_discrepancy(q_workspace, hyper.signal_std).lengthscales
        lengthscales = np.where(np.isfinite(lengthscales), lengthscales, default)
    return Discrepancy(lengthscales, hyper.signal_std)


def expected_squared_errors(
    design_jacobian, q_design, prior_information, eval_jacobian, q_eval, discrepancy: Discrepancy, sigma: float
) -> np.ndarray:
    """(E,) m^2: tr C_e of the module docstring at every workspace configuration, computed directly
    from the full matrices (O((3n)^2) memory; the greedy choice uses the incremental form).
    design_jacobian (n, 3, P) whitened at q_design (n, N) rad; eval_jacobian (E, 3, P) m per display
    unit at q_eval (E, N) rad; prior_information (P, P); sigma (m) the sensor's noise."""
    jw = np.asarray(design_jacobian, dtype=float).reshape(-1, np.shape(eval_jacobian)[-1])
    je = np.asarray(eval_jacobian, dtype=float)
    sigma_matrix = dp.covariance(np.asarray(prior_information, dtype=float) + jw.T @ jw)
    a = np.einsum("eip,pq,kq->eik", je, sigma_matrix, jw)  # J_e Sigma Jw^T (E, 3, 3n)
    k_dd = np.kron(discrepancy.kernel(q_design, q_design), np.eye(3)) / sigma**2
    k_de = discrepancy.kernel(q_design, q_eval)  # (n, E)
    k_ee = np.diagonal(discrepancy.kernel(q_eval, q_eval)) if len(q_eval) else np.zeros(0)
    posterior = np.einsum("eip,pq,eiq->e", je, sigma_matrix, je)
    fitted = np.einsum("eik,kl,eil->e", a, k_dd, a)
    # tr(A_e K_De) / sigma: K_De = k(q_i, q_e) I3 for design point i, so sum over i of tr(A_e[:, i-block]) k
    blocks = a.reshape(len(je), 3, -1, 3)  # (E, 3, n, 3)
    correlated = np.einsum("eini,ne->e", blocks, k_de) / sigma
    return posterior + fitted - 2.0 * correlated + 3.0 * k_ee


@dataclass
class _State:
    """The greedy choice's running sums (module docstring): information, Sigma, B, H (P, P) and U
    (C, 3, P)."""

    information: np.ndarray
    sigma_matrix: np.ndarray
    b: np.ndarray
    h: np.ndarray
    u: np.ndarray

    def sum_of_traces(self, g: np.ndarray) -> float:
        """sum_e tr C_e less the design-free 3 sum_e k(q_e, q_e)."""
        s = self.sigma_matrix
        return float(np.sum(s * g) + np.sum((s @ self.b @ s) * g) - 2.0 * np.trace(s @ self.h))


def _scores(state: _State, jc, hc, uc, kappa: float, g: np.ndarray) -> np.ndarray:
    """(c,) sum_e tr C_e less its design-free part, after adding each candidate: jc (c, 3, P) whitened,
    hc (c, 3, P) its h, uc (c, 3, P) its U, kappa = k(q, q) / sigma^2. Rank-3 forms, with
    Sigma' = Sigma - b R b^T, b = Sigma J_c^T, R = (I + J_c b)^-1, Sigma' J_c^T = b R."""
    s, b_mat, h_mat = state.sigma_matrix, state.b, state.h
    gs = g @ s  # G Sigma
    x = gs @ b_mat  # G Sigma B
    b = np.einsum("pq,ciq->cpi", s, jc)  # (c, P, 3)
    r = np.linalg.inv(np.eye(3) + np.einsum("cip,cpj->cij", jc, b))
    br = b @ r  # Sigma' J_c^T
    bgb = np.einsum("cpi,pq,cqj->cij", b, g, b)
    bbb = np.einsum("cpi,pq,cqj->cij", b, b_mat, b)
    bxb = np.einsum("cpi,pq,cqj->cij", b, x, b)
    bhb = np.einsum("cpi,pq,cqj->cij", b, h_mat, b)
    trace = lambda m: np.trace(m, axis1=-2, axis2=-1)  # noqa: E731
    posterior = np.sum(s * g) - trace(r @ bgb)
    # tr(B Q), Q = Sigma' G Sigma'
    b_q = np.sum((s @ b_mat @ s) * g) - 2.0 * trace(r @ bxb) + trace(r @ bgb @ r @ bbb)
    # Q J_c^T = Sigma G b R - b R (b^T G b) R
    q_jt = np.einsum("qp,cpj->cqj", gs.T, br) - br @ bgb @ r
    u_q = np.einsum("cip,cpi->c", uc, q_jt)
    j_q = trace(np.transpose(br, (0, 2, 1)) @ np.einsum("pq,cqj->cpj", g, br))
    fitted = b_q + 2.0 * u_q + kappa * j_q
    correlated = np.trace(s @ h_mat) - trace(r @ bhb) + np.einsum("cip,cpi->c", hc, br)
    return posterior + fitted - 2.0 * correlated


def robust_design(
    candidate_jacobian,
    q_candidates,
    eval_jacobian,
    q_eval,
    prior_information,
    discrepancy: Discrepancy,
    sigma: float,
    *,
    budget: int | None = None,
    target: float | None = None,
    measured_jacobian=None,
    q_measured=None,
):
    """Choose candidates greedily by the expected squared error across the workspace with the
    discrepancy (module docstring). candidate_jacobian (C, 3, P) whitened at q_candidates (C, N) rad;
    eval_jacobian (E, 3, P) m per display unit at q_eval (E, N) rad; prior_information (P, P);
    sigma (m) the sensor's noise; budget: most configurations; target (m): stop once the expected
    RMS per axis is at or below it. An existing campaign's rows: measured_jacobian (M, 3, P)
    whitened at q_measured (M, N), whose information prior_information already holds; their
    discrepancy is fitted into the parameters too, so they enter B, H and U from the start. A
    `design.Design` (criterion 'robust', statistic 'rms') whose bounds carry expected_rms_mm beside
    the posterior's bounds."""
    from ..planning import design

    if budget is None and target is None:
        raise ValueError("give a budget, a target, or both")
    jc_all = np.asarray(candidate_jacobian, dtype=float)
    je = np.asarray(eval_jacobian, dtype=float)
    q_candidates = np.atleast_2d(np.asarray(q_candidates, dtype=float))
    q_eval = np.atleast_2d(np.asarray(q_eval, dtype=float))
    n_eval, p = je.shape[0], je.shape[2]
    if n_eval == 0:
        raise ValueError("no workspace configurations to take the expected error at")
    g = np.einsum("eip,eiq->pq", je, je)
    k_ce = discrepancy.kernel(q_candidates, q_eval)  # (C, E)
    h_all = (k_ce @ je.reshape(n_eval, -1)).reshape(len(jc_all), 3, p) / sigma
    kappa = discrepancy.signal_std**2 / sigma**2
    constant = 3.0 * float(np.trace(discrepancy.kernel(q_eval, q_eval))) if n_eval else 0.0
    information = np.array(prior_information, dtype=float)
    state = _State(information, dp.covariance(information), np.zeros((p, p)), np.zeros((p, p)), np.zeros_like(jc_all))
    if measured_jacobian is not None and len(measured_jacobian):
        if len(measured_jacobian) > MAX_MEASURED_ROWS:
            raise ValueError(
                f"{len(measured_jacobian)} measured rows: the robust criterion takes at most {MAX_MEASURED_ROWS} "
                "(their discrepancy kernel grows as the rows squared)"
            )
        jm = np.asarray(measured_jacobian, dtype=float)
        q_m = np.atleast_2d(np.asarray(q_measured, dtype=float))
        flat = jm.reshape(-1, p)
        state.b = flat.T @ np.kron(discrepancy.kernel(q_m, q_m), np.eye(3)) @ flat / sigma**2
        h_m = (discrepancy.kernel(q_m, q_eval) @ je.reshape(n_eval, -1)).reshape(len(jm), 3, p) / sigma
        state.h = np.einsum("mip,miq->pq", jm, h_m)
        state.u = np.einsum("mc,mip->cip", discrepancy.kernel(q_m, q_candidates) / sigma**2, jm)
    limit = len(jc_all) if budget is None else min(int(budget), len(jc_all))
    remaining = np.ones(len(jc_all), dtype=bool)
    chosen: list[int] = []
    rows: list[tuple] = []
    expected: list[float] = []

    def record() -> None:
        p95, mean, logdet, _ = design._summary(state.information, je)
        rms = np.sqrt(max(state.sum_of_traces(g) + constant, 0.0) / (3.0 * n_eval))
        rows.append((len(chosen), p95 / MM, mean / MM, logdet))
        expected.append(rms / MM)

    def reached() -> bool:
        return target is not None and expected[-1] * MM <= target

    record()
    stopped = "target" if reached() else "budget"
    while not reached() and len(chosen) < limit:
        left = np.flatnonzero(remaining)
        scores = np.concatenate(
            [
                _scores(state, jc_all[part], h_all[part], state.u[part], kappa, g)
                for part in np.array_split(left, max(1, -(-len(left) // SCORE_CHUNK)))
            ]
        )
        best = int(left[int(np.argmin(scores))])
        remaining[best] = False
        chosen.append(best)
        jb, ub = jc_all[best], state.u[best]
        state.information = state.information + jb.T @ jb
        state.sigma_matrix = dp.covariance(state.information)
        state.b = state.b + ub.T @ jb + jb.T @ ub + kappa * jb.T @ jb
        state.h = state.h + jb.T @ h_all[best]
        state.u = state.u + (discrepancy.kernel(q_candidates, q_candidates[best])[:, 0] / sigma**2)[:, None, None] * jb
        record()
        log.info("%d of at most %d configurations chosen, expected RMS %.4g mm", len(chosen), limit, expected[-1])
        if reached():
            stopped = "target"
    if not reached() and len(chosen) == len(jc_all) and (budget is None or budget > len(chosen)):
        stopped = "candidates"
    bounds = pd.DataFrame(rows, columns=design.BOUND_COLUMNS)
    bounds["expected_rms_mm"] = expected
    return design.Design(np.array(chosen, dtype=int), bounds, CRITERION, "rms", stopped)
