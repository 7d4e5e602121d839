"""The residual GP at 1k, 3k and 10k configurations: wall time of each step on this machine, and
what the approximation costs against the exact GP.

A smooth residual of joints 2 and 4 (0.1-0.3 mm) plus 0.02 mm noise per axis, 7 joints (one never
turned). Steps: hyperparameters (exact marginal likelihood on `SUBSET` evenly spaced rows),
conditioning on every row through `INDUCING` inducing inputs (DTC), the loop's candidate (both,
plus 5 pose-like folds of cross-validation). Accuracy: RMS error of the mean against the true
residual at 2000 new configurations, per axis; at 3k also the exact GP (all rows, O(n^3)) with
the same hyperparameters.

With the residual added to the iiwa's own marker positions, the zero-offset model is fitted
(`evidence.posterior_mode`) and two GP-present computations are timed: the model's parameters
integrated with the GP and its 5-fold cross-validation (`with_parameters.with_gp`: exact n x n
factors up to `with_parameters.MAX_ROWS` rows, Titsias' bound through inducing inputs above), and
the joint-error form against the free GP (`joint_error.joint_error_form`: the joint form on every
row, the free form's hyperparameters on at most `joint_error.MAX_ROWS` rows and above them its
evidence on every row as Titsias' bound). Where the free form can still be searched on every row
(up to `EXACT_FREE_ROWS`), the comparison is also made that way, and the difference between the free
form's two evidences is what the bound and the subsample cost it (how far the comparison leans
towards the joint-error form).

Run from the repository root: python benchmarks/bench_gp.py [sizes...]; writes results/gp.json,
results/gp.md and the table in benchmarks/README.md.
"""

from __future__ import annotations

import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

from remaster.campaigns.robot_model import load_chain
from remaster.inference import blocks, evidence
from remaster.inference.gp import joint_error, kernels, loop_candidate, residual, with_parameters
from remaster.loop import joint_form
from remaster.robot.kinematics import marker_positions

sys.path.insert(0, str(Path(__file__).parent))
from doc_sections import publish  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).parent / "results"
NOISE = 2e-5
MARKER = np.array([0.1, 0.0, 0.02])
EXACT_FREE_ROWS = 3000  # rows up to which the free form is also searched on every row (n x n factors)


def truth(q):
    return np.column_stack([3e-4 * np.sin(2 * q[:, 1]), 2e-4 * np.cos(q[:, 3] + q[:, 1]), 1e-4 * np.sin(3 * q[:, 3])])


def configurations(rng, n):
    q = rng.uniform(-2.0, 2.0, (n, 7))
    q[:, 2] = 0.0
    return q


def with_the_model(chain, q, y, hyper, folds) -> dict:
    """Seconds of the GP-present computations on the zero-offset model of marker positions carrying y."""
    measured = marker_positions(chain, q, MARKER) + y
    model = blocks.paper_model(chain, q, measured, MARKER, np.eye(4), fixed={"zero_offsets.q1": 0.0})
    mode = evidence.posterior_mode(model)
    started = time.perf_counter()
    found = with_parameters.with_gp(mode, q, hyper, folds)
    present = time.perf_counter()
    pseudo = mode.model.whitened(mode.residuals) + (mode.jacobian @ mode.theta).reshape(-1, 3)
    directions = joint_form.joint_directions(chain, model.data, MARKER, np.eye(4), model.values(mode.theta))
    form = joint_error.joint_error_form(q, pseudo, directions, mode.jacobian, model._prior_precision, hyper, 5.0)
    done = time.perf_counter()
    exact = {}
    if joint_error.MAX_ROWS < len(q) <= EXACT_FREE_ROWS:
        subsample, joint_error.MAX_ROWS = joint_error.MAX_ROWS, len(q)
        try:
            every = joint_error.joint_error_form(
                q, pseudo, directions, mode.jacobian, model._prior_precision, hyper, 5.0
            )
        finally:
            joint_error.MAX_ROWS = subsample
        exact = {
            "free_exact_minus_bound_nats": every.log_evidence_free - form.log_evidence_free,
            "exact_preferred": every.preferred,
            "exact_named": every.named,
        }
    return exact | {
        "with_gp_s": present - started,
        "with_gp_method": "exact" if len(q) <= with_parameters.MAX_ROWS else "titsias",
        "with_gp_log_evidence": found.log_evidence,
        "joint_error_s": done - present,
        "joint_error_rows": form.rows,
        "joint_error_preferred": form.preferred,
        "joint_error_named": form.named,
        "joint_error_free_method": form.free_method,
        "joint_error_margin_nats": form.log_evidence_joint - form.log_evidence_free - form.price,
    }


def measure(n: int, rng, new, chain) -> dict:
    q = configurations(rng, n)
    y = truth(q) + rng.normal(0.0, NOISE, (n, 3))
    folds = np.arange(n) // 20 % 5
    started = time.perf_counter()
    hyper = residual.fit_hyperparameters(q, y)
    fitted = time.perf_counter()
    gp = residual.ResidualGP(q, y, hyper)
    conditioned = time.perf_counter()
    loop_candidate.fit_and_score(q, y, y, folds)
    scored = time.perf_counter()
    row = {
        "rows": n,
        "hyperparameters_s": fitted - started,
        "conditioning_s": conditioned - fitted,
        "candidate_s": scored - conditioned,
        "mean_rms_um": float(np.sqrt(np.mean((gp.mean(new) - truth(new)) ** 2)) * 1e6),
        "exact_rms_um": None,
    }
    if n <= 3000:
        cov = kernels.covariance_with_noise(q, hyper)
        mean = kernels.kernel(new, q, hyper) @ np.linalg.solve(cov, y)
        row["exact_rms_um"] = float(np.sqrt(np.mean((mean - truth(new)) ** 2)) * 1e6)
    return row | with_the_model(chain, q, y, hyper, folds)


def gap(r: dict) -> str:
    if "free_exact_minus_bound_nats" not in r:
        return "(exact already)" if r["joint_error_free_method"] == "exact" else "(too large to search)"
    return (
        f"{r['free_exact_minus_bound_nats']:.1f} nats; searched so: {r['exact_preferred']} preferred, named "
        f"{', '.join(r['exact_named']) or 'none'}"
    )


def markdown(record: dict) -> str:
    lines = [
        f"Measured {record['date']} by `bench_gp.py` (seconds on this machine, shared):",
        "",
        "| rows | hyperparameters (600 rows, exact) | conditioning on every row (400 inducing) | loop candidate "
        "(with 5-fold CV) | mean's error | exact GP, same hyperparameters | parameters integrated with the GP, "
        "5-fold CV | joint-error form against the free GP | the free form searched on every row: its evidence "
        "above the bound's |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in record["sizes"]:
        exact = f"{r['exact_rms_um']:.2f} µm" if r["exact_rms_um"] is not None else "(too large to compare)"
        lines.append(
            f"| {r['rows']:,} | {r['hyperparameters_s']:.1f} s | {r['conditioning_s']:.2f} s | {r['candidate_s']:.1f} s "
            f"| {r['mean_rms_um']:.2f} µm | {exact} | {r['with_gp_s']:.1f} s ({r['with_gp_method']}) "
            f"| {r['joint_error_s']:.0f} s on {r['joint_error_rows']:,} rows (free form: "
            f"{'exact' if r['joint_error_free_method'] == 'exact' else 'bound'}), {r['joint_error_preferred']} "
            f"preferred (joint-error form's margin {r['joint_error_margin_nats']:+.0f} nats), named "
            f"{', '.join(r['joint_error_named']) or 'none'} "
            f"| {gap(r)} |"
        )
    return "\n".join(lines)


def main(sizes) -> None:
    rng = np.random.default_rng(0)
    new = configurations(rng, 2000)
    chain = load_chain(
        {"urdf": "data/robots/kuka_iiwa14.urdf", "base": "iiwa_link_0", "flange": "iiwa_link_ee"},
        REPO,
        REPO,
        source="bench_gp",
        name="bench_gp",
    )
    record = {"date": date.today().isoformat(), "sizes": [measure(n, rng, new, chain) for n in sizes]}
    publish(RESULTS, "gp", record, markdown(record), Path(__file__).parent / "README.md")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [1000, 3000, 10000])
