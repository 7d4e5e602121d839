"""A calibration held to a simulated truth it did not make: what `remaster predict` says against where
the true robot puts the marker, at random configurations across the joint limits.

Used by tests/test_truth_claims.py (small campaigns) and benchmarks/bench_truth_claims.py (campaigns
of the paper's size). The campaign goes through the pipeline's own stages in-process (registration,
Laplace fit, loop closure with config.yaml's settings); `compensation.calibrated_robot` and
`compensation.predict` are what `remaster predict` runs. The truth comes from the simulator's record
(`scenario.robot_from_truth`), whose link errors are rigid motions written by other code than the
fit's (`simulation.true_chain`).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from remaster import files
from remaster.analysis import compensation
from remaster.campaigns import folders, scenario
from remaster.campaigns.simulation import true_sensor_positions
from remaster.inference import fit
from remaster.loop import loop_closure
from remaster.loop.report import LoopReport
from remaster.loop.settings import settings_from

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class TruthCheck:
    """effects: what the loop added; validation_rms_per_axis_mm (after the loop) and noise_mm (the
    sensor's per-axis std); error_mm (n,): the true error of `remaster predict`'s position at each
    random configuration, and bound_mm (n,) its per-command 95 % bound; q (n, N) those
    configurations; moved_fraction (N,): the share of each joint's range the optimization set
    spanned."""

    effects: tuple[str, ...]
    validation_rms_per_axis_mm: float
    noise_mm: float
    error_mm: np.ndarray
    bound_mm: np.ndarray
    q: np.ndarray
    moved_fraction: np.ndarray

    @property
    def held_fraction(self) -> float:
        """Share of the random configurations whose true error is within its bound."""
        return float(np.mean(self.error_mm <= self.bound_mm))

    def summary(self) -> dict:
        return {
            "effects": list(self.effects),
            "validation_rms_per_axis_mm": self.validation_rms_per_axis_mm,
            "validation_over_noise": self.validation_rms_per_axis_mm / self.noise_mm,
            "true_error_p95_mm": float(np.quantile(self.error_mm, 0.95)),
            "bound_median_mm": float(np.median(self.bound_mm)),
            "bound_held_fraction": self.held_fraction,
            "joint_range_moved": [round(float(f), 3) for f in self.moved_fraction],
        }


def check(spec: dict, chain, sensor: str, n_random: int = 300, draws: int = 1000, seed: int = 5) -> TruthCheck:
    """Simulate `spec`, calibrate its `sensor` as the pipeline does, and hold `remaster predict`
    (loop model, sensor frame) to the truth at `n_random` configurations uniform within the joint
    limits."""
    simulated = scenario.simulate(spec, chain)
    root = Path(tempfile.mkdtemp())
    folder = root / spec["name"]
    folders.write_campaign(folder, simulated.metadata, simulated.tables)
    files.write_json(root / "truth.json", simulated.truth)
    truth = files.read_json(root / "truth.json")  # as data/truth holds it: plain lists
    campaign = folders.read_campaign(folder, repo_root=REPO)
    config = files.read_yaml(REPO / "config.yaml")
    registered = fit.registration_stage(campaign, sensor)
    laplace = fit.LaplaceReport.of(fit.laplace_stage(campaign, sensor, registered, config["outliers"]["alpha"]))
    settings = settings_from(config["loop_closure"], config["priors"], config["fit"]["cross_check"], config["outliers"])
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
    return TruthCheck(
        tuple(report.effects_added),
        float(report.after["validation"]["rms_per_axis_mm"]),
        float(device.noise) / 1e-3,
        error,
        predicted["bound95_mm"].to_numpy(),
        q,
        moved,
    )
