"""The Snakemake workflow end to end on a tiny simulated campaign: a dry run, a real run, and a
second run that has nothing to do."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from remaster import io, scenario

from .conftest import REPO

SNAKEMAKE = [sys.executable, "-m", "snakemake"]
SMALL_FIT = {"fit": {"paper": {"chains": 2, "samples": 3000, "burn_in": 2000},
                     "default": {"chains": 2, "samples": 4000, "burn_in": 1000},
                     "emcee": {"walkers": 32, "steps": 600, "burn_in": 200}}}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, iiwa):
    """A campaign folder with small sets, written by the simulator, and a config for it."""
    root = tmp_path_factory.mktemp("workflow")
    spec = io.read_yaml(REPO / "data" / "simulation" / "kuka-twin.yaml")
    spec["name"] = "tiny"
    spec["plan"]["sets"] = {"optimization": {"poses": 10, "configurations": 40},
                            "validation": {"poses": 4, "configurations": 16}}
    out = scenario.simulate(spec, iiwa)
    io.write_campaign(root / "raw" / "tiny", out.metadata, out.tables)
    io.write_yaml(root / "config.yaml", {"raw_dir": str(root / "raw"), "results_dir": str(root / "results"),
                                          **SMALL_FIT})
    return root


def run(root, *extra):
    return subprocess.run(SNAKEMAKE + ["-j2", "--configfile", str(root / "config.yaml"), *extra],
                          cwd=REPO, capture_output=True, text=True, timeout=600)


def test_dry_run_lists_the_jobs(tiny):
    result = run(tiny, "-n")
    assert result.returncode == 0, result.stderr
    for rule in ("campaign_summary", "registration", "laplace", "sample", "cross_check", "posterior_summary",
                 "remastering", "table_zero_offsets", "figure_zero_offset_trace"):
        assert rule in result.stdout
    assert not (tiny / "results").exists()


def test_real_run_builds_everything_then_nothing(tiny):
    result = run(tiny)
    assert result.returncode == 0, result.stderr[-3000:]
    results = tiny / "results" / "tiny"
    for sensor in ("motion_capture", "laser_tracker"):
        remastering = io.read_json(results / sensor / "remastering.json")
        assert [j["status"] for j in remastering["joints"]][0].startswith("held")
        assert (results / "figures" / f"zero_offset_trace_{sensor}.pdf").is_file()
    for table in ("zero_offsets", "registration_params"):
        for suffix in (".csv", ".md", ".tex"):
            assert (results / "tables" / f"{table}{suffix}").is_file()
    again = run(tiny)
    assert again.returncode == 0 and "Nothing to be done" in again.stdout + again.stderr


def test_bad_config_is_refused_by_the_schema(tiny):
    io.write_yaml(tiny / "bad.yaml", {"seed": -1})
    result = subprocess.run(SNAKEMAKE + ["-n", "--configfile", str(tiny / "bad.yaml")], cwd=REPO,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode != 0 and "seed" in result.stdout + result.stderr
