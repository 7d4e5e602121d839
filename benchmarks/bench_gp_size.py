"""The residual GP on a dense grid at the size of a real one (about 12,000 rows): is it added, and
does it predict as well as the exact GP on a 3,000-row subset?

A UR-like arm (`arm_kinds.UR5`) measured as the real UR10's series A was: positions on a grid of
joints 1-3 in a region (9 x 9 x 8), each with 19 tool orientations (joints 4-6), measured position by
position; a smooth free-form residual of every joint (random Fourier features, 0.2 mm RMS, short
along joints 1-3 against the grid's spacing, long along the wrist) plus 0.03 mm noise per axis. The
zero-offset model is fitted (`evidence.posterior_mode`) and the loop's candidate
(`loop_candidate.fit_and_score`, pose-grouped folds of whole positions) is scored on its residuals by
the loop's rule (`scoring.judged`, config.yaml's thresholds). Validation: 3 new tool orientations at
each position, the RMS per axis of what is left after each GP's mean, against the exact GP (n x n
factor) conditioned on 3,000 evenly spaced rows with hyperparameters fitted on them the same way.

Beside it, the former fixed 400 inducing inputs at the same hyperparameters: the share of the prior
variance they leave unexplained (`residual.unexplained_share`), Titsias' bound and the evidence gain
through them, and the mean's validation RMS: the cause of the GP not being added at size.

Run from the repository root: python benchmarks/bench_gp_size.py; writes results/gp_size.json,
results/gp_size.md and the table in benchmarks/README.md.
"""

from __future__ import annotations

import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

from remaster import configuration
from remaster.campaigns.arm_kinds import UR5, chain_of
from remaster.inference import blocks, evidence, fit
from remaster.inference.gp import kernels, loop_candidate, residual
from remaster.loop.scoring import judged
from remaster.loop.settings import from_config
from remaster.robot.kinematics import marker_positions

sys.path.insert(0, str(Path(__file__).parent))
from doc_sections import publish  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).parent / "results"
NOISE = 3e-5  # m per axis
FIELD_RMS = 2e-4  # m per axis
MARKER = np.array([0.0, 0.0, 0.09])
FORMER_INDUCING = 400  # the fixed count before `residual.inducing_count`
REFERENCE_ROWS = 3000  # rows of the exact GP compared with
FEATURES = 30
# per-joint frequency scale of the field's Fourier features (rad^-1): short along joints 1-3, long along the wrist
FREQUENCIES = np.array([12.0, 12.0, 12.0, 0.7, 0.7, 0.3])


def positions() -> np.ndarray:
    """(648, 3) rad: joints 1-3 on a 9 x 9 x 8 grid in a region in front of the arm."""
    axes = np.linspace(-0.6, 0.6, 9), np.linspace(-2.0, -1.2, 9), np.linspace(0.8, 1.6, 8)
    return np.array(np.meshgrid(*axes, indexing="ij")).reshape(3, -1).T


def orientations() -> np.ndarray:
    """(19, 3) rad: joints 4-6 about (-pi/2, pi/2, 0), the tool turned in steps."""
    return np.column_stack(
        [
            np.tile(np.linspace(-0.4, 0.4, 5), 4)[:19] - 1.57,
            np.repeat(np.linspace(-0.3, 0.3, 4), 5)[:19] + 1.57,
            np.linspace(-1.5, 1.5, 19),
        ]
    )


def grid(rng) -> tuple[np.ndarray, np.ndarray]:
    """Readings (n, 6) rad in measurement order (every orientation of a position in turn, 1 mrad of
    repeatability) and each row's position (n,), the pose the folds group."""
    where, wrist = positions(), orientations()
    q = np.array([np.concatenate([p, w]) for p in where for w in wrist])
    return q + rng.normal(0.0, 1e-3, q.shape), np.repeat(np.arange(len(where)), len(wrist))


def validation_rows(rng) -> np.ndarray:
    """3 new tool orientations at each position, within the measured wrist ranges."""
    where, wrist = positions(), orientations()
    low, high = wrist.min(axis=0), wrist.max(axis=0)
    return np.array([np.concatenate([p, rng.uniform(low, high)]) for p in where for _ in range(3)])


class Field:
    """A smooth free-form residual (m, robot frame) of all six joints: random Fourier features."""

    def __init__(self, rng):
        self.frequencies = rng.normal(0.0, 1.0, (FEATURES, 6)) * FREQUENCIES
        self.phases = rng.uniform(0.0, 2.0 * np.pi, FEATURES)
        self.weights = rng.normal(0.0, 1.0, (FEATURES, 3)) * FIELD_RMS * np.sqrt(2.0 / FEATURES)

    def __call__(self, q) -> np.ndarray:
        return np.cos(q @ self.frequencies.T + self.phases) @ self.weights


def rms_um(values) -> float:
    return float(np.sqrt(np.mean(np.asarray(values) ** 2)) * 1e6)


def measure() -> dict:
    rng = np.random.default_rng(0)
    chain = chain_of({"robot": UR5, "name": "bench_gp_size"}, REPO)
    settings = from_config(configuration.settings())
    field = Field(np.random.default_rng(5))
    q, poses = grid(rng)
    measured = marker_positions(chain, q, MARKER) + field(q) + rng.normal(0.0, NOISE, (len(q), 3))
    held = fit.identified(blocks.paper_model(chain, q, measured, MARKER, np.eye(4))).held  # what the data cannot fix
    model = blocks.paper_model(chain, q, measured, MARKER, np.eye(4), fixed=held)
    mode = evidence.posterior_mode(model)
    rotation = model.sensor_rotation(mode.theta)
    folds = evidence.pose_folds(poses, settings.cv_folds)
    before = evidence.cross_validate(mode, folds)
    r = model.residuals(mode.theta) @ rotation  # robot frame
    started = time.perf_counter()
    candidate = loop_candidate.fit_and_score(
        q, r, before.held_out @ rotation, folds, int(settings.residual_gp["subset"]), FORMER_INDUCING
    )
    seconds = time.perf_counter() - started
    scores = judged(
        {
            "log_evidence_gain": candidate.log_evidence_gain,
            **evidence.cv_gain(before, evidence.CrossValidation(candidate.mse, candidate.points)),
        },
        settings,
    )
    hyper = candidate.gp.hyper

    q_new = validation_rows(rng)
    measured_new = marker_positions(chain, q_new, MARKER) + field(q_new) + rng.normal(0.0, NOISE, (len(q_new), 3))
    new_model = blocks.paper_model(chain, q_new, measured_new, MARKER, np.eye(4), fixed=held)
    r_new = new_model.residuals(mode.theta) @ rotation

    # the former fixed count, same hyperparameters (the evidence's mode and Occam factor as the candidate's)
    former = residual.ResidualGP(q, r, hyper, FORMER_INDUCING)
    scored = candidate.evidence
    former_bound = residual.titsias_bound(q, r, scored.mode, FORMER_INDUCING)
    m = len(candidate.gp.inducing)

    rows = residual.evenly_spaced(len(q), REFERENCE_ROWS)
    reference_hyper = residual.fit_hyperparameters(q[rows], r[rows], int(settings.residual_gp["subset"]))
    weights = np.linalg.solve(kernels.covariance_with_noise(q[rows], reference_hyper), r[rows])
    reference = kernels.kernel(q_new, q[rows], reference_hyper) @ weights
    after = rms_um(r_new - candidate.gp.mean(q_new))
    exact = rms_um(r_new - reference)
    return {
        "rows": int(len(q)),
        "positions": int(len(np.unique(poses))),
        "field_rms_um": rms_um(field(q)),
        "noise_um": NOISE * 1e6,
        "candidate_s": seconds,
        "hyperparameters": hyper.report(),
        "signal_at_its_floor": any(b.startswith("signal_std") for b in hyper.at_bounds),
        "inducing": m,
        "unexplained_share": residual.unexplained_share(q, hyper, m),
        "log_evidence_gain": candidate.log_evidence_gain,
        "evidence_method": scored.method,
        "cv_mse_fall_in_se": scores["cv_mse_fall_in_se"],
        "added": bool(scores["passed"]),
        "why_not": scores["why_not"],
        "validation_rms_before_um": rms_um(r_new),
        "validation_rms_um": after,
        "exact_subset_rms_um": exact,
        "ratio_to_exact": after / exact,
        "former": {
            "inducing": FORMER_INDUCING,
            "unexplained_share": residual.unexplained_share(q, hyper, FORMER_INDUCING),
            "log_evidence_gain": scored.gain - scored.log_likelihood + former_bound,
            "validation_rms_um": rms_um(r_new - former.mean(q_new)),
        },
    }


def markdown(record: dict) -> str:
    r, f = record["result"], record["result"]["former"]
    hyper = r["hyperparameters"]
    bounds = ", ".join(hyper.get("at_bounds", [])) or "none"
    lengths = ", ".join("-" if v is None else f"{v:.2g}" for v in hyper["lengthscales_rad"])
    return "\n".join(
        [
            f"Measured {record['date']} by `bench_gp_size.py` ({r['rows']:,} rows at {r['positions']} positions; "
            f"field {r['field_rms_um']:.0f} µm RMS per axis, noise {r['noise_um']:.0f} µm; seconds on this "
            "machine, shared):",
            "",
            "| inducing inputs | prior variance unexplained at the other rows | evidence gain (Titsias' bound) | "
            "validation RMS per axis after the GP's mean | added by the loop's rule |",
            "|---|---|---|---|---|",
            f"| {f['inducing']} (former, fixed) | {f['unexplained_share']:.1%} | {f['log_evidence_gain']:+,.0f} nats "
            f"| {f['validation_rms_um']:.1f} µm | {'yes' if f['log_evidence_gain'] > 5 else 'no'} (evidence) |",
            f"| {r['inducing']} (`inducing_count`) | {r['unexplained_share']:.1%} | {r['log_evidence_gain']:+,.0f} "
            f"nats | {r['validation_rms_um']:.1f} µm | {'yes' if r['added'] else 'no: ' + r['why_not']} "
            f"(cross-validated fall {r['cv_mse_fall_in_se']:.1f} SE) |",
            "",
            f"Before the GP the validation RMS per axis is {r['validation_rms_before_um']:.1f} µm; the exact GP "
            f"on 3,000 evenly spaced rows (hyperparameters fitted on them) leaves {r['exact_subset_rms_um']:.1f} µm: "
            f"the loop's GP is {r['ratio_to_exact']:.2f} times that. Its hyperparameters: lengthscales "
            f"{lengths} rad, signal {hyper['signal_std_m'] * 1e6:.0f} µm, noise {hyper['noise_std_m'] * 1e6:.0f} µm; "
            f"at a bound: {bounds}. The candidate took {r['candidate_s']:.0f} s.",
        ]
    )


def main() -> None:
    record = {"date": date.today().isoformat(), "result": measure()}
    publish(RESULTS, "gp_size", record, markdown(record), Path(__file__).parent / "README.md")


if __name__ == "__main__":
    main()
