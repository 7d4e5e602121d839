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

from .. import configuration, files, identity, spatial
from ..calibration import prediction
from ..campaigns import folders, scenario
from ..campaigns.simulation import true_marker_positions, true_sensor_positions
from ..evaluation import workspace
from ..evaluation.acceptance import Acceptance
from ..inference import metrics
from ..loop.result import LoopReport
from ..robot import kinematics
from ..units import DEG
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
    arrays: `error_mm`, `bound_mm`, `paper_error_mm`; `determined`: whether predict states the bound as
    determined; `own_outside`: `posterior_outside` there), None
    without them; own_posterior: what the
    calibration's own posterior expects of the seed-level statistics near the data
    (`own_posterior_expectations`); ranks: simulation-based calibration, the truth's normalized rank
    among the posterior's draws, each taken as the arm (`_Truth.ranks`): {'pit_near', 'pit_across',
    'pit_validation': the mean PIT over the commands inside the measured ranges, across the limits,
    at the validation set (`mean_pit_rank`); 'p95_near': the registered p95 inside the measured
    ranges (`posterior_p95`); 'zero_offsets.q<j>': each estimated zero-offset's recoverable truth
    (`recoverable_zero_offsets`)}, each {'rank': in [0, 1], 'truth': its value, ...}; calibration:
    the `Calibration` itself (its campaign, fits and loop closure), for what else a caller holds it to."""

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
    ranks: dict | None = None
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
    campaign, truth = simulated_campaign(spec, chain, repo_root)
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
    where = {"near": (q_domain, domain_error), "across": (q, error), "validation": (q_planned, planned_error)}
    ranks = held.ranks(where, q_domain, np.random.default_rng([probe.seed, 2]))
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
        ranks,
        calibration,
    )


def simulated_campaign(spec: dict, chain, repo_root) -> tuple:
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
        error, bound, _ = self.predicted(q, rng, model)
        return error, bound

    def predicted(self, q, rng, model: str = "loop") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`errors` and (n,) bool whether `remaster predict` states each bound as determined (near the
        data, no held joint moved: its `determined` column)."""
        at = predict(self.calibration, q, model=model, frame="sensor", draws=self.draws, seed=rng)
        error = np.linalg.norm(at[["x", "y", "z"]].to_numpy() - self.true_points(q), axis=1) / 1e-3
        return error, at["bound95_mm"].to_numpy(), at["determined"].to_numpy(dtype=bool)

    def claims(self, q_domain, probe: Probe) -> dict[str, Claim]:
        """The loop model's workspace claims (registered, without noise) near the data (q_domain)
        and across the limits, each against the true p95 of its posterior mean's registered error: the
        mean the claim is made about, the residual GP's correction included where the loop added it."""
        campaign = self.calibration.campaign
        random = prediction.robot_configurations(
            campaign.chain, identity.robot_identity(campaign), probe.n_random, probe.seed
        )
        held = {}
        for where, configurations in (("domain", q_domain), ("random", random)):
            mean = self.robot.robot_points(configurations)
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

    def ranks(self, errors: Mapping[str, tuple], q_domain, rng) -> dict:
        """`TruthCheck.ranks` of errors {where: (q (n, N) rad, the truth's error there (n,) mm)}, the
        workspace p95 at q_domain and the estimated zero-offsets, each with the truth's own value."""
        out = {}
        for where, (q, error) in errors.items():
            pit, rank = mean_pit_rank(error, posterior_errors(self.robot, q, self.draws, rng))
            out[f"pit_{where}"] = {"rank": rank, "truth": pit}
        chain = self.calibration.campaign.chain
        true_points = true_marker_positions(chain, self.true_robot, self.device, q_domain, np.zeros(len(q_domain)))
        registered = metrics.registered_distances(self.robot.robot_points(q_domain), true_points[None])[0]
        p95, draws = float(np.quantile(registered, 0.95) / 1e-3), posterior_p95(self.robot, q_domain, self.draws, rng)
        out["p95_near"] = {
            "rank": float(normalized_rank(p95, draws)),
            "truth": p95,
            "draws_median": float(np.median(draws)),
        }
        return {**out, **self.zero_offset_ranks()}

    def zero_offset_ranks(self) -> dict:
        """{name: rank, the recoverable truth (rad), its z-score} of each zero-offset the loop
        estimated, among the loop's posterior samples of it (`recoverable_zero_offsets`), and
        z_certified, k_certified: its z against the certificate's correction and combined standard
        uncertainty (U / k: the posterior std, u_between and u_model), that U's coverage factor k and
        u_model / (U / k) (absent where the certificate gives no U)."""
        loop, chain = self.calibration.loop, self.calibration.campaign.chain
        table = loop.report.parameters
        estimated = (table["status"] == "estimated") & table["parameter"].astype(str).str.startswith("zero_offsets.")
        truth = recoverable_zero_offsets(chain, self.true_robot)
        certified = self.calibration.corrections().set_index("joint")
        out = {}
        for name in table.loc[estimated, "parameter"].astype(str):
            j = int(name.split(".q")[-1]) - 1
            draws, value = loop.samples[name].to_numpy(float), float(truth[j])
            z = (value - draws.mean()) / draws.std()
            out[name] = {"rank": float(normalized_rank(value, draws)), "truth": value, "z": float(z)}
            row = certified.loc[chain.joint_names[j]]
            u_c = float(row["U_deg"]) / float(row["k"]) * DEG  # the certificate's combined standard uncertainty
            if np.isfinite(u_c) and u_c > 0:
                out[name]["z_certified"] = float((value - float(row["correction_rad"])) / u_c)
                out[name]["k_certified"] = float(row["k"])
                out[name]["u_model_fraction"] = float(np.nan_to_num(row["u_model_deg"]) * DEG / u_c)
        return out

    def elsewhere(self, q, rng) -> dict:
        """`TruthCheck.elsewhere` at configurations q (m, N) rad (drawn after everything else of
        `check`, so that it changes none of it)."""
        q = np.asarray(q, dtype=float)
        loop_error, loop_bound, determined = self.predicted(q, rng)
        paper_error, _ = self.errors(q, rng, "paper")
        return {
            "error_mm": loop_error,
            "bound_mm": loop_bound,
            "determined": determined,
            "paper_error_mm": paper_error,
            "own_outside": posterior_outside(self.robot, q, loop_bound, self.draws, rng),
        }


def posterior_errors(robot, q, count: int, rng) -> np.ndarray:
    """(count, n) mm: each of `count` fresh posterior draws of `robot` (a calibrated robot) taken as
    the arm's truth, the distance of its marker at command q_i (n, N) from the prediction (sensor
    frame, as `remaster predict` states it): what the arm's true error would be, its residual field
    drawn as one arm's across the commands (`draw_points(jointly=True)`)."""
    in_sensor, _ = robot.draw_points(q, "sensor", count, rng, jointly=True)
    mean = robot.in_frame(robot.robot_points(q), "sensor")
    return np.linalg.norm(in_sensor - mean, axis=-1) / 1e-3


def posterior_outside(robot, q, bound_mm, count: int, rng) -> np.ndarray:
    """(count, n) bool: each of `count` fresh posterior draws taken as the arm's truth
    (`posterior_errors`), whether its marker lies outside the per-command bound bound_mm (n,)."""
    return posterior_errors(robot, q, count, rng) > np.asarray(bound_mm)[None]


def posterior_p95(robot, q, count: int, rng) -> np.ndarray:
    """(count,) mm: each of `count` fresh posterior draws taken as the arm's truth, the 95th
    percentile over configurations q (n, N) of its registered distance from the posterior mean
    (robot frame): the arm's p95 the workspace claim bounds, its residual field drawn as one
    (`draw_points(jointly=True)`)."""
    in_robot, _ = robot.draw_points(q, "robot", count, rng, jointly=True)
    return np.quantile(metrics.registered_distances(robot.robot_points(q), in_robot), 0.95, axis=1) / 1e-3


def own_posterior_expectations(robot, q, bound_mm, claim_mm: float, count: int, rng) -> dict:
    """What a calibrated posterior expects of one arm, each of `count` fresh posterior draws taken
    as the arm's truth, at configurations q (n, N): the chance that more than a quarter of the
    commands fall outside their per-command bound bound_mm (n,), and that the workspace claim
    claim_mm (the bound on one arm's p95, registered) is within 0.8-2 times the arm's p95, and
    covers it (about 0.95 when the claim and the draws agree). What the truth does is then compared
    with these chances: a rate the posterior itself expects is not a miscalibration."""
    outside = np.mean(posterior_outside(robot, q, bound_mm, count, rng), axis=1)
    ratio = claim_mm / posterior_p95(robot, q, count, rng)
    return {
        "outside_above_25": float(np.mean(outside > 0.25)),
        "claim_in_window": float(np.mean((ratio >= 0.8) & (ratio <= 2.0))),
        "claim_covers": float(np.mean(ratio >= 1.0)),
    }


def normalized_rank(value, draws) -> np.ndarray:
    """The rank of value (...) among draws (K, ...) along their first axis, over K: the share of the
    draws below it, ties counted half, in [0, 1]. Uniform over truths when each truth is one more
    draw of the distribution the draws come from (simulation-based calibration, Talts et al. 2018);
    a truth in the draws' lower tail gives about 0, in their upper tail about 1."""
    draws, value = np.asarray(draws, dtype=float), np.asarray(value, dtype=float)
    return (np.sum(draws < value, axis=0) + 0.5 * np.sum(draws == value, axis=0)) / len(draws)


def mean_pit_rank(error_mm, draw_errors_mm) -> tuple[float, float]:
    """(the truth's mean PIT over n commands, its rank among the draws' own mean PITs): error_mm (n,)
    the truth's error at each command, draw_errors_mm (K, n) each posterior draw's taken as the arm
    (`posterior_errors`). An arm's PIT at a command is the rank of its error among the draws' there
    (`normalized_rank`; a draw's among the K - 1 others); the truth's mean over the commands is
    ranked among the K draws' means, which carry the same correlation across commands: a test
    quantity of the arm, uniform over seeds when the posterior is calibrated (Modrak et al. 2023)."""
    draws = np.asarray(draw_errors_mm, dtype=float)
    truth = float(np.mean(normalized_rank(error_mm, draws)))
    own = np.argsort(np.argsort(draws, axis=0), axis=0) / (len(draws) - 1)
    return truth, float(normalized_rank(truth, own.mean(axis=1)))


def link_turns(chain, motions) -> np.ndarray:
    """(N,) rad: the part of the simulator's rigid link motions (N + 1, 6) that turns about each
    joint's own axis, which no measurement tells from that joint's zero-offset: the motion of F_j
    (moved on the side it starts from, M_j F_j = F_j D_j) about axis j, and the motion of the next
    fixed transform, which starts in joint j's turned frame, about it too (the tool's after the last
    joint). The iiwa's consecutive axes are perpendicular, so no turn is counted for two joints."""
    transforms = np.concatenate([chain.joint_transforms, chain.tool_transform[None]])
    moves = spatial.homogeneous(spatial.rpy_to_matrix(*motions[:, 3:].T), motions[:, :3])
    own = kinematics.small_motion_of(np.linalg.inv(transforms) @ moves @ transforms)[:-1, 3:]
    following = spatial.matrix_to_rotation_vector(moves[1:, :3, :3])
    return np.sum((own + following) * chain.joint_axes, axis=1)


def recoverable_zero_offsets(chain, true_robot) -> np.ndarray:
    """(N,) rad: the zero-offsets a fit can recover of a true robot (`simulation.TrueRobot`): its own,
    each turned by its link motions' turn about the joint's axis (`link_turns`)."""
    offsets = np.asarray(true_robot.zero_offsets, dtype=float)
    return offsets if true_robot.link_motions is None else offsets + link_turns(chain, true_robot.link_motions)
