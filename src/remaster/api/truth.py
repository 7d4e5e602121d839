"""A calibration held to a simulated truth it did not make: what `remaster predict` says against where
the true robot puts the marker, at random configurations across the joint limits and at random
configurations inside the measured joint ranges (`domain.MeasuredDomain`); and the workspace claims
(`workspace.workspace_accuracy`: the loop-closed model, registration fitted, without noise as the
truth is noise-free, the bound on one arm's 95th percentile) inside the measured ranges and across
the limits against the true 95th percentile of the registered error there.

What the tests (tests/workflow/test_truth_claims.py, tests/loop/test_joint_harmonics.py: small
campaigns) and the benchmarks (benchmarks/truth_claims.py and those that use it: campaigns of the
paper's size) hold the tool to. The campaign is simulated, written to a temporary folder and read
back as the workflow reads it, then calibrated by `calibrate` (the pipeline's own stages
in-process); `Calibration.robot` and `compensation.predict` are what `remaster predict` runs. The
truth comes from the simulator's record (`scenario.robot_from_truth`), whose link errors are rigid
motions written by other code than the fit's (`simulation.true_chain`).
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import configuration, files, identity
from ..calibration import prediction
from ..campaigns import folders, scenario
from ..campaigns.simulation import true_marker_positions, true_sensor_positions
from ..evaluation import workspace
from ..evaluation.acceptance import Acceptance
from ..inference import metrics
from ..loop.result import LoopReport
from .calibration import Calibration, calibrate
from .use import predict


@dataclass(frozen=True)
class Probe:
    """How `check` holds a calibration to its truth: n_random configurations in each domain (across
    the joint limits, inside the measured ranges), draws posterior draws for every bound and claim,
    seed of every stage's generator and of the configurations; without: candidate effects the loop
    closure is not offered; settings: the configuration (config.yaml's content or part of it; the
    schema's defaults for the rest), whose accuracy section n_random and draws replace."""

    n_random: int = 300
    draws: int = 1000
    seed: int = 5
    without: tuple[str, ...] = ()
    settings: Mapping[str, Any] | None = None

    def configuration(self) -> dict:
        config = configuration.settings(self.settings)
        config["accuracy"] = {**config["accuracy"], "draws": self.draws, "random_configurations": self.n_random}
        return config


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
    (`own_posterior_expectations`); calibration: the `Calibration` itself (its campaign, fits and
    loop closure), for what else a caller holds it to."""

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
    calibration: Calibration | None = None

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


def check(spec: dict, chain, sensor: str, probe: Probe = Probe(), elsewhere_q=None, repo_root=None) -> TruthCheck:
    """Simulate `spec` (its robot `chain`), calibrate its `sensor` as the pipeline does (`calibrate`,
    probe's settings and seed), and hold `remaster predict` (loop model, sensor frame) to the truth
    at probe.n_random configurations uniform within the joint limits and as many near the measured
    configurations; and the loop model's workspace claims near the data and across the limits to the
    true 95th percentile there; with the acceptance test. With elsewhere_q (m, N) rad, e.g. another
    design's commands: both models' `remaster predict` there against the truth (`TruthCheck.elsewhere`).
    repo_root: where the campaign's shared URDF is (default: the current directory)."""
    campaign, truth = _simulated(spec, chain, repo_root)
    calibration = calibrate(campaign, sensor, probe.configuration(), seed=probe.seed, without=probe.without)
    robot, rng = calibration.robot("loop"), np.random.default_rng(probe.seed)
    device = scenario.sensor_from_truth(truth, sensor, campaign.sensors[sensor].marker)
    held = _Truth(calibration, robot, device, scenario.robot_from_truth(truth), probe.draws)
    lower, upper = np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi)
    q = rng.uniform(lower, upper, (probe.n_random, chain.n_joints))
    error, bound = held.errors(q, rng)
    # inside the measured domain: the workspace claims' own configurations there
    data, laplace = campaign.sensors[sensor], calibration.laplace
    q_domain = workspace.fit_domain(campaign.chain, data, laplace.outlier_rows).configurations(
        identity.robot_identity(campaign), probe.n_random, probe.seed
    )
    domain_error, domain_bound = held.errors(q_domain, rng)
    claims = held.claims(q_domain, probe)
    # at the validation set's commands (drawn after everything above, so that it changes none of it)
    q_planned = data.q("validation")
    planned_error, planned_bound = held.errors(q_planned, rng)
    elsewhere = None if elsewhere_q is None else held.elsewhere(elsewhere_q, rng)
    # its own generator, so that it changes nothing above
    own = own_posterior_expectations(
        robot,
        q_domain,
        domain_bound,
        claims["domain"].p95_bound_mm,
        probe.draws,
        np.random.default_rng([probe.seed, 1]),
    )
    report = calibration.loop.report
    return TruthCheck(
        calibration.effects,
        float(report.after["validation"]["rms_per_axis_mm"]),
        float(device.noise) / 1e-3,
        error,
        bound,
        q,
        np.ptp(data.q("optimization"), axis=0) / (upper - lower),
        domain_error,
        domain_bound,
        q_domain,
        claims,
        report,
        data.fit_readings(laplace.outlier_rows),
        planned_error,
        planned_bound,
        q_planned,
        calibration.loop.samples,
        calibration.acceptance,
        elsewhere,
        own,
        calibration,
    )


def _simulated(spec: dict, chain, repo_root) -> tuple:
    """(the campaign, its truth) of `spec` simulated, written to a temporary folder and read back as
    the workflow reads them (the truth as data/truth holds it: plain lists)."""
    simulated = scenario.simulate(spec, chain)
    with tempfile.TemporaryDirectory() as temporary:
        root = Path(temporary)
        folders.write_campaign(root / spec["name"], simulated.metadata, simulated.tables)
        files.write_json(root / "truth.json", simulated.truth)
        truth = files.read_json(root / "truth.json")
        return folders.read_campaign(root / spec["name"], repo_root=repo_root), truth


@dataclass(frozen=True, eq=False)
class _Truth:
    """A calibration beside the truth it is held to: the loop model's calibrated robot, the true
    sensor (`scenario.sensor_from_truth`) and the true robot; draws posterior draws per bound."""

    calibration: Calibration
    robot: Any
    device: Any
    true_robot: Any
    draws: int

    def true_points(self, q) -> np.ndarray:
        """(n, 3) m: where the true robot puts the marker at q (n, N), in the sensor's frame."""
        chain = self.calibration.campaign.chain
        return true_sensor_positions(chain, self.true_robot, self.device, q, np.zeros(len(q)))

    def errors(self, q, rng, model: str = "loop") -> tuple[np.ndarray, np.ndarray]:
        """(true error of `remaster predict` (sensor frame) at q (n, N), its per-command 95 % bound), mm."""
        at = predict(self.calibration, q, model=model, frame="sensor", draws=self.draws, seed=rng)
        error = np.linalg.norm(at[["x", "y", "z"]].to_numpy() - self.true_points(q), axis=1) / 1e-3
        return error, at["bound95_mm"].to_numpy()

    def claims(self, q_domain, probe: Probe) -> dict[str, Claim]:
        """The loop model's workspace claims (registered, without noise) near the data (q_domain)
        and across the limits, each against the true p95 of its posterior mean's registered error."""
        campaign, sensor = self.calibration.campaign, self.calibration.sensor
        loop = prediction.loop_calibration(self.calibration.loop.report, self.calibration.loop.samples)
        random = prediction.robot_configurations(
            campaign.chain, identity.robot_identity(campaign), probe.n_random, probe.seed
        )
        held = {}
        for where, configurations in (("domain", q_domain), ("random", random)):
            mean = loop.predictor(campaign.chain, configurations, campaign.sensors[sensor].marker).points(loop.values)
            true_points = true_marker_positions(
                campaign.chain, self.true_robot, self.device, configurations, np.zeros(len(configurations))
            )
            registered = metrics.registered_distances(mean, true_points[None])[0]
            row = workspace.claim_rows(self.calibration.claims, "loop", where, noise="without noise").iloc[0]
            held[where] = Claim(
                float(row["p95_mm"]),
                float(row["p95_bound_mm"]),
                float(np.quantile(registered, 0.95) / 1e-3),
                float(row["p95_bound_data_mm"]),
            )
        return held

    def elsewhere(self, q, rng) -> dict:
        """`TruthCheck.elsewhere` at configurations q (m, N) rad (drawn after everything else of
        `check`, so that it changes none of it)."""
        q = np.asarray(q, dtype=float)
        loop_error, loop_bound = self.errors(q, rng)
        paper_error, _ = self.errors(q, rng, "paper")
        return {
            "error_mm": loop_error,
            "bound_mm": loop_bound,
            "paper_error_mm": paper_error,
            "own_outside": posterior_outside(self.robot, q, loop_bound, self.draws, rng),
        }


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
