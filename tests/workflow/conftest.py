"""The workflow tests' shared set-up: a tiny pair of simulated campaigns with a config of small
fits, and how a test runs Snakemake on them."""

import subprocess

import pytest

from remaster import files
from remaster.campaigns import folders, scenario

from ..conftest import REPO, SNAKEMAKE

SMALL_FIT = {
    "fit": {
        "paper": {"chains": 2, "samples": 3000, "burn_in": 2000},
        "default": {"chains": 2, "samples": 4000, "burn_in": 1000},
        "emcee": {"walkers": 32, "steps": 600, "burn_in": 200},
    },
    "accuracy": {"draws": 200, "random_configurations": 100},
    "loop_closure": {"mcmc": {"chains": 2, "samples": 1500, "burn_in": 500}},
}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, iiwa):
    """Two campaign folders with small sets, written by the simulator, and a config for them."""
    root = tmp_path_factory.mktemp("workflow")
    for name, scenario_file in (("tiny", "kuka-twin.yaml"), ("tiny2", "kuka-compliance.yaml")):
        spec = files.read_yaml(REPO / "data" / "simulation" / scenario_file)
        spec["name"] = name
        spec["plan"]["sets"] = {
            "optimization": {"poses": 10, "configurations": 40},
            "validation": {"poses": 4, "configurations": 16},
        }
        out = scenario.simulate(spec, iiwa)
        folders.write_campaign(root / "raw" / name, out.metadata, out.tables)
    files.write_yaml(
        root / "config.yaml", {"raw_dir": str(root / "raw"), "results_dir": str(root / "results"), **SMALL_FIT}
    )
    return root


def run(root, *extra, config="config.yaml"):
    return subprocess.run(
        SNAKEMAKE + ["-j2", "--configfile", str(root / config), *extra],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )


def with_results(root, name, **settings):
    """A config like the one in `root` (with `settings` changed), writing to another results folder."""
    config = files.read_yaml(root / "config.yaml")
    files.write_yaml(root / f"{name}.yaml", {**config, **settings, "results_dir": str(root / name)})
    return f"{name}.yaml"
