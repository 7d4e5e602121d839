"""How each stage's cost grows with the rows of a campaign: wall time and peak memory per stage at
several sizes, and the fitted growth exponent (time ~ rows^b).

Run from the repository root: python benchmarks/bench_scale.py [rows ...]   (default 1000 3000 10000)
One simulated campaign per size (the iiwa, a laser tracker, random configurations four to a pose,
70 % optimization / 30 % validation, known zero-offsets and compliance), written in the campaign
format and read back. Stages, with the workflow's settings from config.yaml unless said:
read (parse and check the campaign), registration, laplace (outliers, identifiability, fit),
paper chain (time per step of the paper's Metropolis, from a short chain: the full chain is
2e5 steps), default sampler (its configured length), accuracy (every metric, 2000 draws),
loop closure (every candidate, the refit). Peak memory is Python's and NumPy's allocations
(tracemalloc) above what was held before the stage.
"""

from __future__ import annotations

import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd

from remaster import files, seeding
from remaster.campaigns import folders
from remaster.campaigns.simulation import Sensor, TrueRobot, looking_at, measure
from remaster.evaluation import accuracy
from remaster.inference import fit
from remaster.inference.laplace_report import LaplaceReport
from remaster.loop import loop_closure
from remaster.loop.settings import settings_from

REPO = Path(__file__).resolve().parents[1]
PAPER_STEPS = 2_000  # per chain, half burn-in: enough to time a step


def write_campaign(folder: Path, rows: int, rng: np.random.Generator) -> None:
    chain = folders.read_campaign(REPO / "data" / "raw" / "kuka-compliance", repo_root=REPO).chain
    per_pose = 4
    q = rng.uniform(np.maximum(chain.lower, -2.0), np.minimum(chain.upper, 2.0), (rows, chain.n_joints))
    marker = np.array([-0.1, 0.0, 0.02])
    sensor = Sensor("laser_tracker", "laser_tracker", looking_at([1.6, 0.3, 1.2], [0, 0, 0.6]), 1e-5, marker)
    truth = TrueRobot(
        zero_offsets=rng.normal(0.0, np.radians(0.3), chain.n_joints),
        joint_compliance=np.full(chain.n_joints, 1e-4),
        payload_mass=1.0,
    )
    n_opt = int(0.7 * rows) // per_pose * per_pose
    index = np.arange(rows)
    table = pd.DataFrame(
        {
            "set": np.where(index < n_opt, "optimization", "validation"),
            "pose": np.where(index < n_opt, index, index - n_opt) // per_pose,
            "solution": index % per_pose,
        }
    )
    table[[f"q{j + 1}" for j in range(chain.n_joints)]] = q
    table[["x", "y", "z"]] = measure(chain, truth, sensor, q, rng)
    metadata = {
        "name": f"scale-{rows}",
        "date": "2020-01-01",
        "description": "bench_scale",
        "robot": {
            "urdf": str(REPO / "data" / "robots" / "kuka_iiwa14.urdf"),
            "base": "iiwa_link_0",
            "flange": "iiwa_link_ee",
        },
        "sensors": {"laser_tracker": {"kind": "laser_tracker", "marker": marker.tolist(), "noise": 1e-5}},
    }
    folders.write_campaign(folder, metadata, {"laser_tracker": table})


def measured(stage, *args, **kw):
    """(result, seconds, peak bytes above the start) of stage(*args, **kw)."""
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    started = time.perf_counter()
    result = stage(*args, **kw)
    seconds = time.perf_counter() - started
    return result, seconds, tracemalloc.get_traced_memory()[1] - before


def stages(folder: Path, config: dict) -> list[dict]:
    sensor, seed = "laser_tracker", config["seed"]
    out = []

    def record(name, result_seconds_peak, per=1):
        result, seconds, peak = result_seconds_peak
        out.append({"stage": name, "seconds": seconds / per, "peak_mb": peak / 1e6})
        return result

    campaign = record("read", measured(folders.read_campaign, folder))
    registration = record("registration", measured(fit.registration_stage, campaign, sensor))
    laplace = LaplaceReport.of(
        record("laplace", measured(fit.laplace_stage, campaign, sensor, registration, config["outliers"]))
    )
    paper = {**config["fit"]["paper"], "samples": PAPER_STEPS, "burn_in": PAPER_STEPS // 2}
    record(
        "paper chain, per step",
        measured(
            fit.sampling_stage,
            campaign,
            sensor,
            registration,
            laplace,
            {"paper": paper},
            {"paper": seeding.generator(seed, "scale", "paper")},
        ),
        per=paper["chains"] * paper["samples"],
    )
    samples, _, _ = record(
        "default sampler",
        measured(
            fit.sampling_stage,
            campaign,
            sensor,
            registration,
            laplace,
            {"default": config["fit"]["default"]},
            {"default": seeding.generator(seed, "scale", "default")},
        ),
    )["default"]
    record(
        "accuracy",
        measured(
            accuracy.accuracy_tables,
            campaign,
            sensor,
            registration,
            laplace,
            samples,
            seeding.generator(seed, "scale", "accuracy"),
            config["accuracy"]["draws"],
            config["accuracy"]["random_configurations"],
        ),
    )
    settings = settings_from(config["loop_closure"], config["priors"], config["fit"]["cross_check"], config["outliers"])
    record(
        "loop closure",
        measured(
            loop_closure.loop_closure_stage,
            campaign,
            sensor,
            registration,
            laplace,
            seeding.generator(seed, "scale", "loop"),
            settings,
        ),
    )
    return out


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [1000, 3000, 10000]
    config = files.read_yaml(REPO / "config.yaml")
    rows = []
    with tempfile.TemporaryDirectory() as root:  # compiled kernels loaded and caches warm before timing
        write_campaign(Path(root, "scale-200"), 200, np.random.default_rng(0))
        stages(Path(root, "scale-200"), config)
    tracemalloc.start()
    for n in sizes:
        with tempfile.TemporaryDirectory() as root:
            folder = Path(root, f"scale-{n}")  # a campaign folder is named as the campaign
            write_campaign(folder, n, np.random.default_rng(n))
            for row in stages(folder, config):
                rows.append({"rows": n, **row})
                print(f"{n:>7} rows  {row['stage']:<22} {row['seconds']:10.4g} s  {row['peak_mb']:9.1f} MB", flush=True)
    table = pd.DataFrame(rows)
    if len(sizes) > 1:
        print("\ngrowth exponent b of time ~ rows^b (least squares over the sizes), and of peak memory:")
        for stage, part in table.groupby("stage", sort=False):
            b_time = np.polyfit(np.log(part["rows"]), np.log(part["seconds"]), 1)[0]
            b_memory = np.polyfit(np.log(part["rows"]), np.log(np.maximum(part["peak_mb"], 1e-3)), 1)[0]
            print(f"  {stage:<22} time {b_time:5.2f}   memory {b_memory:5.2f}")


if __name__ == "__main__":
    main()
