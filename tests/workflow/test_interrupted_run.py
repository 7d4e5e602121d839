"""A run killed half way and started again gives the results an undisturbed run gives, to the byte.
In its own file, so the suite's workers run it beside test_workflow's runs."""

import os
import signal
import subprocess
import time

import pytest

from ..conftest import REPO
from .conftest import SNAKEMAKE, run, with_results

pytestmark = pytest.mark.workflow  # runs Snakemake: deselect with -m "not workflow"


SENSOR = "laser_tracker"  # one sensor's jobs: the other's would add time, not checks


def result_bytes(folder, campaign):
    """The remastering file, the loop closure's tables and samples (its report holds timings), the
    samples and metrics of one sensor of a campaign in a run, as bytes."""
    patterns = [
        f"{campaign}/{SENSOR}/remastering.json",
        f"{campaign}/{SENSOR}/loop_closure/*",
        f"{campaign}/{SENSOR}/fit/summary.csv",
        f"{campaign}/{SENSOR}/fit/samples_*.parquet",
        f"{campaign}/{SENSOR}/metrics/*.csv",
    ]
    return {str(p.relative_to(folder)): p.read_bytes() for pattern in patterns for p in sorted(folder.glob(pattern))}


@pytest.mark.slow  # a real workflow run of minutes
def test_a_run_killed_half_way_completes_with_identical_results(tiny):
    """A second run of one of the two campaigns into another folder, killed while sampling and
    started again: it finishes, and every result of one of its sensors (samples, loop closure,
    metrics, remastering) equals the first, undisturbed run's to the byte (so the same inputs and
    seed give the same results, whether or not a run was interrupted, and whichever other campaigns
    the configuration lists). Both runs ask for those results only: the other sensor, figures and the
    report would add time, not checks (test_workflow's run builds them)."""
    first = tiny / "results"
    wanted = [str(first / "tiny" / SENSOR / name) for name in ("remastering.json", "loop_closure.json")]
    undisturbed = run(tiny, "--", *wanted)  # both campaigns configured
    assert undisturbed.returncode == 0, undisturbed.stderr[-3000:]
    killed = with_results(tiny, "results_killed", campaigns=["tiny"])
    targets = [str(tiny / "results_killed" / name) for name in result_bytes(first, "tiny")]
    process = subprocess.Popen(
        SNAKEMAKE + ["-j2", "--configfile", str(tiny / killed), "--", *targets],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while not list((tiny / "results_killed").glob("tiny/*/fit/samples_*.parquet")) and time.monotonic() < deadline:
        time.sleep(0.2)
    os.killpg(process.pid, signal.SIGKILL)  # the whole job tree, as a power cut or a scheduler would
    process.wait()
    assert not all(os.path.exists(target) for target in targets)  # killed before its end
    # what a person does after a kill (README): release the lock the killed run held, run again
    assert run(tiny, "--unlock", config=killed).returncode == 0
    again = run(tiny, "--", *targets, config=killed)
    assert again.returncode == 0, again.stderr[-3000:]
    a, b = result_bytes(first, "tiny"), result_bytes(tiny / "results_killed", "tiny")
    assert a.keys() == b.keys() and len(a) > 15
    assert [name for name in a if a[name] != b[name]] == []
