"""How often the claims of the loop-closed model cover the truth, inside the measured joint ranges and
across the joint limits: the twin re-simulated.

Run from the repository root: python benchmarks/bench_claim_coverage.py [sensor] [first seed] [count]
(default laser_tracker, seeds 10-29). Each seed simulates the twin scenario again: the same robot and
truth (its link errors, rigid motions of every fixed transform in the simulator's own form, come from
their own seed), new poses and noise. Each campaign goes through
registration, the paper's fit and the loop closure with config.yaml's settings; its claims
(`evaluation.workspace`, 400 draws, registration fitted, without noise as the truth is noise-free) at
300 random configurations across
the joint limits and at 300 inside the measured joint ranges (joint 3 held at 0, as the twin's planner
holds it) are held against the simulator's true marker positions there. Printed per seed: the rms of
z = (posterior mean - truth) / posterior std over the loop's compliance and drift parameters, the worst
z, and per domain the true 95 % quantile of the error, the pooled claimed 95 % quantile and the bound
on one arm's 95 % quantile; then how often each covers the truth.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from remaster import files, identity
from remaster.calibration import prediction
from remaster.campaigns import folders, scenario
from remaster.campaigns.simulation import true_marker_positions
from remaster.evaluation import workspace
from remaster.inference import fit, metrics
from remaster.inference.laplace_report import LaplaceReport
from remaster.inference.parameter_blocks import block_parameters
from remaster.inference.posterior_summary import mode_summary
from remaster.loop import loop_closure
from remaster.loop.result import LoopReport, LoopResults
from remaster.loop.settings import settings_from
from remaster.robot import kinematics
from remaster.units import SECONDS_PER_HOUR

REPO = Path(__file__).resolve().parents[1]
DRAWS, RANDOM, SEED = 400, 300, 20181113


def true_parameters(truth: dict, chain) -> dict[str, float]:
    """The loop blocks' parameters as the simulator drew them (SI), named as the blocks name them:
    compliance and drift (the link geometry's truth is not in the fit's parametrization)."""
    effects = truth["effects"]
    n = chain.n_joints
    compliance = block_parameters("joint_compliance", chain).names[:n]  # the torque terms, not the payload's
    out = dict(zip(compliance, effects["joint_compliance"]["compliance_rad_per_Nm"]))
    rates = np.radians(effects["drift"]["zero_offset_rate_deg_per_hour"]) / SECONDS_PER_HOUR
    out |= dict(zip(block_parameters("drift", chain).names, rates))
    # the link errors are rigid motions in the simulator's own form, not the fit's parameters: they
    # are held to the truth through the positions they give (the quantiles below), not one by one
    return out


def one_seed(spec: dict, chain, config: dict, sensor: str, seed: int) -> dict:
    simulated = scenario.simulate(spec, chain, seed=seed)
    folder = Path(tempfile.mkdtemp()) / spec["name"]
    folders.write_campaign(folder, simulated.metadata, simulated.tables)
    files.write_json(folder.parent / "truth.json", simulated.truth)
    truth = files.read_json(folder.parent / "truth.json")  # as data/truth holds it: plain lists
    campaign = folders.read_campaign(folder, repo_root=REPO)
    registered = fit.registration_stage(campaign, sensor)
    laplace = LaplaceReport.of(fit.laplace_stage(campaign, sensor, registered, config["outliers"]))
    settings = settings_from(config["loop_closure"], config["priors"], config["fit"]["cross_check"], config["outliers"])
    result = loop_closure.loop_closure_stage(
        campaign, sensor, registered, laplace, np.random.default_rng(SEED), settings
    )
    result.report.write(folder.parent / "loop.json")
    report, samples = LoopReport.read(folder.parent / "loop.json"), result.samples
    robot = identity.robot_identity(campaign)
    claims = workspace.workspace_accuracy(
        campaign.chain,
        campaign.sensors[sensor],
        robot,
        mode_summary(laplace),
        laplace,
        LoopResults(report, samples),
        np.random.default_rng(SEED),
        prediction.Propagation(DRAWS, RANDOM, SEED),
    ).claims
    marker = campaign.sensors[sensor].marker
    device = scenario.sensor_from_truth(truth, sensor, marker)
    calibration = prediction.loop_calibration(report, samples)
    q_sets = {
        "random": prediction.robot_configurations(campaign.chain, robot, RANDOM, SEED),
        "domain": workspace.fit_domain(campaign.chain, campaign.sensors[sensor], laplace.outlier_rows).configurations(
            robot, RANDOM, SEED
        ),
    }
    parameters = true_parameters(truth, campaign.chain)
    z = {n: (samples[n].mean() - v) / samples[n].std() for n, v in parameters.items() if n in samples}
    worst = max(z, key=lambda n: abs(z[n]))
    row = {
        "seed": seed,
        "rms_z": float(np.sqrt(np.mean(np.square(list(z.values()))))),
        "worst": worst,
        "worst_z": float(z[worst]),
    }
    for where, q in q_sets.items():
        claim = workspace.claim_rows(claims, "loop", where, noise="without noise").iloc[0]
        true_points = true_marker_positions(
            campaign.chain, scenario.robot_from_truth(truth), device, q, np.zeros(len(q))
        )
        points = calibration.predictor(campaign.chain, q, marker).points(calibration.values)
        true_p95 = np.quantile(metrics.registered_distances(points, true_points[None])[0], 0.95) / 1e-3
        row |= {
            f"{where}_true_p95_mm": float(true_p95),
            f"{where}_p95_mm": float(claim["p95_mm"]),
            f"{where}_p95_bound_mm": float(claim["p95_bound_mm"]),
        }
    return row


def main() -> None:
    sensor = sys.argv[1] if len(sys.argv) > 1 else "laser_tracker"
    first = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    count = int(sys.argv[3]) if len(sys.argv) > 3 else 20
    urdf = REPO / "data" / "robots" / "kuka_iiwa14.urdf"
    chain = kinematics.chain_from_urdf(urdf.read_text(), "iiwa_link_0", "iiwa_link_ee", source=str(urdf))
    spec = files.read_yaml(REPO / "data" / "simulation" / "kuka-twin.yaml")
    config = files.read_yaml(REPO / "config.yaml")
    rows = []
    for seed in range(first, first + count):
        rows.append(one_seed(spec, chain, config, sensor, seed))
        r = rows[-1]
        print(
            f"seed {seed}: rms z {r['rms_z']:.2f}, worst {r['worst']} z {r['worst_z']:+.2f}; "
            + "; ".join(
                f"{where}: true p95 {r[f'{where}_true_p95_mm']:.4f} mm, claimed p95 {r[f'{where}_p95_mm']:.4f}, "
                f"bound {r[f'{where}_p95_bound_mm']:.4f}"
                for where in ("domain", "random")
            ),
            flush=True,
        )
    table = pd.DataFrame(rows)
    for where in ("domain", "random"):
        for column in ("p95_mm", "p95_bound_mm"):
            covered = int((table[f"{where}_{column}"] >= table[f"{where}_true_p95_mm"]).sum())
            print(f"{where} {column} covers the true 95 % quantile in {covered} of {len(table)} campaigns")
            print(
                f"{where} {column} range {table[f'{where}_{column}'].min():.4f}-{table[f'{where}_{column}'].max():.4f} "
                f"mm; true {table[f'{where}_true_p95_mm'].min():.4f}-{table[f'{where}_true_p95_mm'].max():.4f} mm"
            )


if __name__ == "__main__":
    main()
