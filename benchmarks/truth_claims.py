"""A calibration held to a simulated truth it did not make: what `remaster predict` says against where
the true robot puts the marker, at random configurations across the joint limits and at random
configurations inside the measured joint ranges (`domain.MeasuredDomain`); and the workspace claims
(`workspace.workspace_accuracy`: the loop-closed model, registration fitted, without noise as the
truth is noise-free, the bound on one arm's 95th percentile) inside the measured ranges and across the limits against the true 95th
percentile of the registered error there.

Not a benchmark itself: the harness that tests/workflow/test_truth_claims.py and tests/loop/test_joint_harmonics.py
(small campaigns) and benchmarks/bench_truth_claims.py and bench_cyclic_case.py (campaigns of the
paper's size) share, with the config.yaml the workflow runs (validated against its schema, defaults
filled). The campaign goes through the pipeline's own stages in-process (registration,
Laplace fit, loop closure with config.yaml's settings); `compensation.calibrated_robot` and
`compensation.predict` are what `remaster predict` runs. The truth comes from the simulator's record
(`scenario.robot_from_truth`), whose link errors are rigid motions written by other code than the
fit's (`simulation.true_chain`).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from snakemake.utils import validate

from remaster import files, identity
from remaster.calibration import compensation, prediction
from remaster.campaigns import folders, scenario
from remaster.campaigns.simulation import true_marker_positions, true_sensor_positions
from remaster.evaluation import acceptance, workspace
from remaster.evaluation.acceptance import Acceptance
from remaster.inference import blocks, evidence, fit, metrics
from remaster.loop import loop_closure, selection
from remaster.loop.result import LoopReport, LoopResults
from remaster.loop.settings import settings_from

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Claim:
    """The workspace claim of the loop-closed model at one set of configurations (registration
    fitted, without noise), mm: p95 (pooled) and p95_bound (one arm's 95th percentile, the
    certificate's), against the true 95th percentile of the registered error of its posterior
    mean there (noise-free); p95_bound_data_mm: the bound's part the data determine
    (`workspace.priors_decide`: below half of it the certificate says "not determined")."""

    p95_mm: float
    p95_bound_mm: float
    true_p95_mm: float
    p95_bound_data_mm: float = float("nan")

    @property
    def determined(self) -> bool:
        return not workspace.priors_decide(self.p95_bound_mm, self.p95_bound_data_mm)

    @property
    def covers(self) -> bool:
        return self.p95_bound_mm >= self.true_p95_mm


@dataclass(frozen=True)
class TruthCheck:
    """effects: what the loop added; validation_rms_per_axis_mm (after the loop) and noise_mm (the
    sensor's per-axis std); error_mm (n,): the true error of `remaster predict`'s position at each
    random configuration across the joint limits, and bound_mm (n,) its per-command 95 % bound; q
    (n, N) those configurations; moved_fraction (N,): the share of each joint's range the
    optimization set spanned; domain_error_mm, domain_bound_mm, domain_q: the same at random
    configurations inside the measured joint ranges; claims: {'domain', 'random': Claim}; report:
    the loop closure's report as read back from its file; measured_q (m, N): the optimization
    readings the fit used (the measured domain's rows); planned_error_mm, planned_bound_mm, planned_q:
    the same as error_mm and bound_mm at the validation set's commands (the planner's own
    configurations, drawn like the measured ones, not between them); samples: the loop closure's
    posterior samples (SI); acceptance: the acceptance test on the validation set (config.yaml's
    settings); elsewhere: at configurations another design measured (`check`'s elsewhere_q), the
    loop model's true error and per-command bound and the zero-offset model's true error (mm,
    arrays: `error_mm`, `bound_mm`, `paper_error_mm`; `own_outside`: `posterior_outside` there), None
    without them; own_posterior: what the
    calibration's own posterior expects of the seed-level statistics near the data
    (`own_posterior_expectations`)."""

    effects: tuple[str, ...]
    validation_rms_per_axis_mm: float
    noise_mm: float
    error_mm: np.ndarray
    bound_mm: np.ndarray
    q: np.ndarray
    moved_fraction: np.ndarray
    domain_error_mm: np.ndarray
    domain_bound_mm: np.ndarray
    domain_q: np.ndarray
    claims: dict[str, Claim]
    report: LoopReport | None = None
    measured_q: np.ndarray | None = None
    planned_error_mm: np.ndarray | None = None
    planned_bound_mm: np.ndarray | None = None
    planned_q: np.ndarray | None = None
    samples: pd.DataFrame | None = None
    acceptance: Acceptance | None = None
    elsewhere: dict | None = None
    own_posterior: dict | None = None

    @property
    def held_fraction(self) -> float:
        """Share of the random configurations across the limits whose true error is within its bound."""
        return float(np.mean(self.error_mm <= self.bound_mm))

    @property
    def domain_held_fraction(self) -> float:
        """Share of the random configurations inside the measured ranges whose true error is within its bound."""
        return float(np.mean(self.domain_error_mm <= self.domain_bound_mm))

    @property
    def planned_held_fraction(self) -> float:
        """Share of the validation set's commands whose true error is within its bound."""
        return float(np.mean(self.planned_error_mm <= self.planned_bound_mm))

    def summary(self) -> dict:
        return {
            "effects": list(self.effects),
            "validation_rms_per_axis_mm": self.validation_rms_per_axis_mm,
            "validation_over_noise": self.validation_rms_per_axis_mm / self.noise_mm,
            "true_error_p95_mm": float(np.quantile(self.error_mm, 0.95)),
            "bound_median_mm": float(np.median(self.bound_mm)),
            "bound_held_fraction": self.held_fraction,
            "domain_true_error_p95_mm": float(np.quantile(self.domain_error_mm, 0.95)),
            "domain_bound_median_mm": float(np.median(self.domain_bound_mm)),
            "domain_bound_held_fraction": self.domain_held_fraction,
            "claims": {
                where: {"true_p95_mm": c.true_p95_mm, "p95_mm": c.p95_mm, "p95_bound_mm": c.p95_bound_mm}
                for where, c in self.claims.items()
            },
            "joint_range_moved": [round(float(f), 3) for f in self.moved_fraction],
        }


def check(
    spec: dict,
    chain,
    sensor: str,
    n_random: int = 300,
    draws: int = 1000,
    seed: int = 5,
    without: tuple = (),
    elsewhere_q=None,
) -> TruthCheck:
    """Simulate `spec`, calibrate its `sensor` as the pipeline does (the loop closure offered every
    candidate but those `without`), and hold `remaster predict` (loop model, sensor frame) to the
    truth at `n_random` configurations uniform within the joint limits and `n_random` near the
    measured configurations; and the loop model's workspace claims (`draws` posterior draws,
    `n_random` configurations each) near the data and across the limits to the true 95th percentile
    there; and run the acceptance test. With elsewhere_q (m, N) rad, e.g. another design's
    commands: both models' `remaster predict` there against the truth (`TruthCheck.elsewhere`)."""
    simulated = scenario.simulate(spec, chain)
    root = Path(tempfile.mkdtemp())
    folder = root / spec["name"]
    folders.write_campaign(folder, simulated.metadata, simulated.tables)
    files.write_json(root / "truth.json", simulated.truth)
    truth = files.read_json(root / "truth.json")  # as data/truth holds it: plain lists
    campaign = folders.read_campaign(folder, repo_root=REPO)
    config = files.read_yaml(REPO / "config.yaml")
    validate(
        config, str(REPO / "workflow" / "schemas" / "config.schema.yaml")
    )  # the schema's defaults, as the workflow fills them
    registered = fit.registration_stage(campaign, sensor)
    laplace = fit.LaplaceReport.of(fit.laplace_stage(campaign, sensor, registered, config["outliers"]["alpha"]))
    settings = settings_from(config["loop_closure"], config["priors"], config["fit"]["cross_check"], config["outliers"])
    settings = replace(settings, candidates=tuple(c for c in settings.candidates if c not in without))
    result = loop_closure.loop_closure_stage(
        campaign, sensor, registered, laplace, np.random.default_rng(seed), settings
    )
    result.report.write(root / "loop.json")
    report = LoopReport.read(root / "loop.json")
    results = {
        "registration": registered,
        "laplace": laplace,
        "summary": fit.mode_summary(laplace),
        "paper_samples": None,
        "loop": report,
        "loop_samples": result.samples,
        "gp": None,
    }
    robot = compensation.calibrated_robot(campaign, sensor, "loop", results)
    rng = np.random.default_rng(seed)
    lower, upper = np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi)
    q = rng.uniform(lower, upper, (n_random, chain.n_joints))
    predicted = compensation.predict(robot, q, "sensor", draws, rng)
    device = scenario.sensor_from_truth(truth, sensor, campaign.sensors[sensor].marker)
    true = true_sensor_positions(campaign.chain, scenario.robot_from_truth(truth), device, q, np.zeros(len(q)))
    error = np.linalg.norm(predicted[["x", "y", "z"]].to_numpy() - true, axis=1) / 1e-3
    optimization = campaign.sensors[sensor].q("optimization")
    moved = np.ptp(optimization, axis=0) / (upper - lower)
    true_robot = scenario.robot_from_truth(truth)
    # inside the measured domain: the workspace claims' own configurations there
    robot_key = identity.robot_identity(campaign)
    q_domain = workspace.fit_domain(campaign.chain, campaign.sensors[sensor], laplace.outlier_rows).configurations(
        robot_key, n_random, seed
    )
    at_domain = compensation.predict(robot, q_domain, "sensor", draws, rng)
    true_domain = true_sensor_positions(campaign.chain, true_robot, device, q_domain, np.zeros(len(q_domain)))
    domain_error = np.linalg.norm(at_domain[["x", "y", "z"]].to_numpy() - true_domain, axis=1) / 1e-3
    claims = workspace.workspace_accuracy(
        campaign.chain,
        campaign.sensors[sensor],
        robot_key,
        results["summary"],
        laplace,
        LoopResults(report, result.samples),
        np.random.default_rng(seed),
        prediction.Propagation(draws, n_random, seed),
    ).claims
    loop = prediction.loop_calibration(report, result.samples)
    held_to_truth = {}
    for where, configurations in (
        ("domain", q_domain),
        ("random", prediction.robot_configurations(campaign.chain, robot_key, n_random, seed)),
    ):
        mean = loop.predictor(campaign.chain, configurations, campaign.sensors[sensor].marker).points(loop.values)
        true_points = true_marker_positions(
            campaign.chain, true_robot, device, configurations, np.zeros(len(configurations))
        )
        registered = metrics.registered_distances(mean, true_points[None])[0]
        row = workspace.claim_rows(claims, "loop", where, noise="without noise").iloc[0]
        held_to_truth[where] = Claim(
            float(row["p95_mm"]),
            float(row["p95_bound_mm"]),
            float(np.quantile(registered, 0.95) / 1e-3),
            float(row["p95_bound_data_mm"]),
        )
    # at the validation set's commands (drawn after everything above, so that it changes none of it)
    q_planned = campaign.sensors[sensor].q("validation")
    at_planned = compensation.predict(robot, q_planned, "sensor", draws, rng)
    true_planned = true_sensor_positions(campaign.chain, true_robot, device, q_planned, np.zeros(len(q_planned)))
    planned_error = np.linalg.norm(at_planned[["x", "y", "z"]].to_numpy() - true_planned, axis=1) / 1e-3
    accepted = acceptance.acceptance_stage(
        campaign,
        sensor,
        results["registration"].t_nr,
        laplace,
        None,
        LoopResults(report, result.samples, result.gp),
        np.random.default_rng(seed),
        config["acceptance"],
    )
    elsewhere = None if elsewhere_q is None else _elsewhere(campaign, sensor, results, elsewhere_q, truth, draws, rng)
    # its own generator, so that it changes nothing above
    own = own_posterior_expectations(
        robot,
        q_domain,
        at_domain["bound95_mm"].to_numpy(),
        held_to_truth["domain"].p95_bound_mm,
        draws,
        np.random.default_rng([seed, 1]),
    )
    return TruthCheck(
        tuple(report.effects_added),
        float(report.after["validation"]["rms_per_axis_mm"]),
        float(device.noise) / 1e-3,
        error,
        predicted["bound95_mm"].to_numpy(),
        q,
        moved,
        domain_error,
        at_domain["bound95_mm"].to_numpy(),
        q_domain,
        held_to_truth,
        report,
        campaign.sensors[sensor].fit_readings(laplace.outlier_rows),
        planned_error,
        at_planned["bound95_mm"].to_numpy(),
        q_planned,
        result.samples,
        accepted,
        elsewhere,
        own,
    )


def posterior_outside(robot, q, bound_mm, count: int, rng) -> np.ndarray:
    """(count, n) bool: each of `count` fresh posterior draws of `robot` (a calibrated robot) taken as
    the arm's truth, whether its marker at command q_i (n, N) lies outside the per-command bound
    bound_mm (n,) about the prediction (sensor frame, as `remaster predict` states it)."""
    in_sensor, _ = robot.draw_points(q, "sensor", count, rng)
    mean = robot.in_frame(robot.robot_points(q), "sensor")
    return np.linalg.norm(in_sensor - mean, axis=-1) / 1e-3 > np.asarray(bound_mm)[None]


def own_posterior_expectations(robot, q, bound_mm, claim_mm: float, count: int, rng) -> dict:
    """What a calibrated posterior expects of one arm, each of `count` fresh posterior draws taken
    as the arm's truth, at configurations q (n, N): the chance that more than a quarter of the
    commands fall outside their per-command bound bound_mm (n,), and that the workspace claim
    claim_mm (the bound on one arm's p95, registered) is within 0.8-2 times the arm's p95, and
    covers it (about 0.95 when the claim and the draws agree). What the truth does is then compared
    with these chances: a rate the posterior itself expects is not a miscalibration."""
    outside = np.mean(posterior_outside(robot, q, bound_mm, count, rng), axis=1)
    in_robot, _ = robot.draw_points(q, "robot", count, rng)
    p95 = np.quantile(metrics.registered_distances(robot.robot_points(q), in_robot), 0.95, axis=1) / 1e-3
    ratio = claim_mm / p95
    return {
        "outside_above_25": float(np.mean(outside > 0.25)),
        "claim_in_window": float(np.mean((ratio >= 0.8) & (ratio <= 2.0))),
        "claim_covers": float(np.mean(ratio >= 1.0)),
    }


def _elsewhere(campaign, sensor: str, results: dict, q, truth: dict, draws: int, rng) -> dict:
    """`TruthCheck.elsewhere` at configurations q (m, N) rad (drawn after everything else of
    `check`, so that it changes none of it)."""
    q = np.asarray(q, dtype=float)
    device = scenario.sensor_from_truth(truth, sensor, campaign.sensors[sensor].marker)
    true = true_sensor_positions(campaign.chain, scenario.robot_from_truth(truth), device, q, np.zeros(len(q)))
    # as the workflow reads summary.csv: the parameter a column
    results = {**results, "summary": results["summary"].reset_index()}
    out, robots = {}, {}
    for model in ("loop", "paper"):
        robots[model] = compensation.calibrated_robot(campaign, sensor, model, results)
        predicted = compensation.predict(robots[model], q, "sensor", draws, rng)
        out[model] = (
            np.linalg.norm(predicted[["x", "y", "z"]].to_numpy() - true, axis=1) / 1e-3,
            predicted["bound95_mm"].to_numpy(),
        )
    return {
        "error_mm": out["loop"][0],
        "bound_mm": out["loop"][1],
        "paper_error_mm": out["paper"][0],
        "own_outside": posterior_outside(robots["loop"], q, out["loop"][1], draws, rng),
    }


def least_squares_validation(campaign, sensor: str, registered, laplace, settings, extensions, priors=None) -> dict:
    """The baseline a calibration engineer would fit: least squares of the paper's model plus
    `extensions` (e.g. every link's six parameters, the marker offset, joint compliance) on the
    optimization rows the paper's fit kept; flat (`priors` None: what the data cannot see held at 0,
    by the loop's own reduction) or under `priors`; the gravity torques as `settings.model` gives
    them on this campaign's chain. Returns the validation set's accuracy (`selection.accuracy`:
    rmse_mm, rms_per_axis_mm, ...) and the parameters fitted; the validation set is read for this only."""
    data = campaign.sensors[sensor]
    fitted_on = blocks.readings(campaign.chain, data, "optimization", settings.model, exclude=laplace.outlier_rows)
    checked_on = blocks.readings(campaign.chain, data, "validation", settings.model)
    model, _ = blocks.extended_model(
        campaign.chain, fitted_on, data.marker, registered.t_nr, extensions, dict(laplace.held), priors
    )
    theta = evidence.posterior_mode(model, np.zeros(len(model.names))).theta
    validation = model.on(checked_on)
    poses = data.table["pose"].to_numpy()[checked_on.rows]
    return {**selection.accuracy(validation.measured, validation.predict(theta), poses), "parameters": len(theta)}
