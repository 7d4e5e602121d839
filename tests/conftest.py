"""Shared fixtures: the bundled iiwa model and a DH robot (UR5 nominal table); the workflow's
configuration with the schema's defaults, and the loop closure's settings and report from it."""

import dataclasses
import os
import sys
import time
from pathlib import Path

if os.environ.get("PYTEST_XDIST_WORKER"):
    # one BLAS thread per worker, set before NumPy loads it: the workers already fill the cores, and
    # each worker's BLAS threading on top of them would have the cores switching between threads
    for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(variable, "1")

import numpy as np
import pytest

from remaster.campaigns.arm_kinds import UR5_DH
from remaster.robot import kinematics

REPO = Path(__file__).resolve().parents[1]
SCHEMA = REPO / "src" / "remaster" / "data" / "config.schema.yaml"
IIWA_URDF = REPO / "data" / "robots" / "kuka_iiwa14.urdf"
UR5_URDF = Path(__file__).resolve().parent / "data" / "ur5_nominal.urdf"
# Snakemake as the tests run it: the suite's workers run several workflows at once from the
# repository folder, each into its own results folder, which remaster locks itself
# (`remaster.results.take_lock`); Snakemake's lock of the shared working folder would stop them.
SNAKEMAKE = [sys.executable, "-m", "snakemake", "--nolock"]
# UR5_DH (`arm_kinds`): Universal Robots UR5 nominal standard DH table; ur5_nominal.urdf is the same chain.


@pytest.fixture(scope="session")
def iiwa():
    return kinematics.chain_from_urdf(IIWA_URDF.read_text(), "iiwa_link_0", "iiwa_link_ee", source=str(IIWA_URDF))


@pytest.fixture(scope="session")
def ur5_dh():
    return kinematics.chain_from_dh(UR5_DH, "standard", name="ur5")


@pytest.fixture
def rng():
    return np.random.default_rng(20181113)


def validated_config(config=None) -> dict:
    """A copy of `config` (default: none at all) validated against the workflow's schema, with its
    defaults filled in as the workflow fills them (`remaster.configuration.settings`): the schema is
    the one place they live."""
    from remaster.configuration import settings

    return settings(config)


def loop_settings(config=None, **changes):
    """The loop closure's settings (`remaster.loop.settings.LoopSettings`) of a configuration
    (`validated_config`: the schema's defaults where it says nothing), with `changes` to its fields."""
    from remaster.loop.settings import from_config

    return dataclasses.replace(from_config(validated_config(config)), **changes)


def loop_report(parameters=(), effects=(), closure=None, source="loop_closure.json", **fields):
    """A loop closure's report (`remaster.loop.result.LoopReport`) as read from its file, with what
    the later stages read: the refit's parameter rows, the effects added, the closure test, and
    neutral values for the rest (1 kg tool plate, the industrial class's priors, no tracker noise model,
    no gross error, no between-design component); `fields` overrides any top-level key."""
    from remaster.loop.result import LoopReport
    from remaster.robot import priors

    accuracy = {s: {"rmse_mm": 0.02, "rms_per_axis_mm": 0.01} for s in ("optimization", "validation")}
    content = {
        "sensor": "laser_tracker",
        "evidence": "",
        "selection_data": "optimization set only",
        "settings": {
            "payload_mass_kg": 1.0,
            "payload_com_m": [0.0, 0.0, 0.02],
            "priors": {"std_display_units": dict(priors.DEFAULTS["industrial"])},
            "harmonic_orders": 1,
        },
        "effects_added": list(effects),
        "explained_fraction_when_added": {},
        "candidates": {},
        "rounds": [],
        "validation_rmse_before_mm": 0.02,
        "validation_rmse_after_mm": 0.02,
        "sigma_before_mm": 0.01,
        "sigma_after_mm": 0.01,
        "before": accuracy,
        "after": accuracy,
        "identifiability": {"dropped": {}},
        "prior_dominated": [],
        "warnings": [],
        "refit": {"parameters": list(parameters)},
        "zero_offset_shifts": [],
        "closure": dict(closure or {}),
        "residual_gp": None,
        "noise_model": {"offered": False, "chosen": "isotropic", "why": "not a laser tracker"},
        "gross_errors": {"optimization": [], "validation": [], "with_flagged_rows": {}},
        "between_design": {m: {"groups": 0, "method": "not computed", "parameters": {}} for m in ("paper", "loop")},
        **fields,
    }
    return LoopReport.of(content, source)


def assert_documents_show(benchmark: str, results: str) -> None:
    """benchmarks/results/<results>.md and the documents' blocks (`DOCUMENTS`, between `BEGIN` and
    `END`) are `benchmarks/<benchmark>.py`'s own rendering of <results>.json: no number in them is
    typed by hand."""
    import importlib.util
    import json
    import sys

    sys.path.insert(0, str(REPO / "benchmarks"))  # a benchmark may import its sibling
    spec = importlib.util.spec_from_file_location(benchmark, REPO / "benchmarks" / f"{benchmark}.py")
    bench = importlib.util.module_from_spec(spec)
    sys.modules[benchmark] = bench  # its dataclasses look their module up there
    spec.loader.exec_module(bench)
    written = json.loads((REPO / "benchmarks" / "results" / f"{results}.json").read_text())
    assert bench.markdown(written) == (REPO / "benchmarks" / "results" / f"{results}.md").read_text()
    for document, block in zip(bench.DOCUMENTS, bench.document_blocks(written)):
        assert f"{bench.BEGIN}\n{block}{bench.END}" in document.read_text(), document


# A test whose call (not its fixtures) takes over this many seconds of processor time fails unless
# marked slow or workflow: the quick suite stays quick. Processor time, not wall time, so a test is
# judged by its own cost, not by what else the machine runs (the suite's workers, other jobs).
# REMASTER_TEST_LIMIT_S overrides it (0: no limit).
TEST_LIMIT_S = float(os.environ.get("REMASTER_TEST_LIMIT_S", "60"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    started = time.process_time()
    yield
    item.processor_seconds = time.process_time() - started


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    marked = any(item.get_closest_marker(m) for m in ("slow", "workflow"))
    spent = getattr(item, "processor_seconds", 0.0)
    if call.when == "call" and report.passed and TEST_LIMIT_S and not marked and spent > TEST_LIMIT_S:
        report.outcome = "failed"
        report.longrepr = (
            f"{item.nodeid} took {spent:.0f} s of processor time, over the {TEST_LIMIT_S:.0f} s a test not marked "
            "slow may take: mark it @pytest.mark.slow, or share its expensive set-up through a session fixture "
            "(tests/support)"
        )


def pytest_collection_modifyitems(items):
    """Files with a workflow test first, then files with a slow one, then the rest: the suite's
    workers (pytest-xdist, a file to a worker, in this order: `--no-loadscope-reorder` in addopts,
    where xdist would put the files with the most tests first) start the longest files first, so no
    long file is left to run alone at the end."""
    weight = {"workflow": 0, "slow": 1}
    files: dict = {}
    for item in items:
        marked = (weight[m.name] for m in item.iter_markers() if m.name in weight)
        files[item.path] = min(files.get(item.path, 2), min(marked, default=2))
    items.sort(key=lambda item: files[item.path])  # stable: a file's tests stay together, in order
