"""`remaster.api`: the configuration with the schema's defaults (the same the workflow fills in),
and a small simulated campaign calibrated, predicted at, compensated and compared in-process."""

import ast
import copy
import subprocess
import sys

import numpy as np
import pytest

import remaster
from remaster import api, configuration, files
from remaster.api import stages
from remaster.campaigns import folders, scenario
from remaster.campaigns.arm_kinds import chain_of, iiwa_rigid_link_errors
from remaster.errors import InputError

from .conftest import REPO


@pytest.mark.parametrize("given", [{}, files.read_yaml(REPO / "config.yaml")], ids=["nothing", "config.yaml"])
def test_settings_fill_the_defaults_the_workflow_fills(given):
    """The workflow validates config.yaml against the package's schema through Snakemake; `settings`
    gives the same configuration without Snakemake, and leaves what it was given unchanged."""
    from snakemake.utils import validate

    by_snakemake = copy.deepcopy(given)
    validate(by_snakemake, str(configuration.SCHEMA))
    before = copy.deepcopy(given)
    assert api.settings(given) == by_snakemake
    assert given == before


def test_settings_lay_a_part_over_the_defaults_and_refuse_what_the_schema_refuses():
    settings = api.settings({"accuracy": {"draws": 300}, "loop_closure": {"residual_gp": {"enabled": False}}})
    assert settings["accuracy"] == {"draws": 300, "random_configurations": 1000}
    assert settings["loop_closure"]["residual_gp"]["enabled"] is False
    assert settings["loop_closure"]["residual_gp"]["subset"] == api.settings()["loop_closure"]["residual_gp"]["subset"]
    with pytest.raises(InputError) as refused:
        api.settings({"loop_closure": {"cv_folds": 1}})
    assert refused.value.key == "loop_closure/cv_folds" and "minimum" in refused.value.reason
    with pytest.raises(InputError, match="'acuracy' was unexpected"):
        api.settings({"acuracy": {}})


def test_the_package_exports_the_interface():
    assert remaster.calibrate is api.calibrate and remaster.settings is api.settings
    with pytest.raises(AttributeError):
        remaster.calibrat  # noqa: B018


def test_the_interface_and_its_stages_load_nothing_heavy_until_a_name_is_used():
    """Each workflow job is a fresh Python: `from remaster import api` and `remaster.api.stages`
    import none of the library's stages, and a stage used loads its own module, not the others'."""
    modules = sorted({module for module, _ in stages.STAGES.values()})
    code = (
        "import sys\nfrom remaster import api\nimport remaster.api.stages\n"
        "def loaded():\n"
        f"    return [m for m in {modules!r} if 'remaster.' + m in sys.modules]\n"
        "light = [m for m in ('remaster.api.calibration', 'remaster.api.use', 'remaster.configuration')"
        " if m in sys.modules]\n"
        "before = loaded()\napi.stages.draw_campaign_figure\n"
        "print(light, before, loaded())"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[] [] ['reporting.campaign_figures']"


def test_every_stage_is_a_function_of_its_module_and_the_names_behave_as_imported():
    import importlib

    assert list(stages.STAGES) == stages.__all__ and set(stages.__all__) <= set(dir(stages))
    for name, (module, attribute) in stages.STAGES.items():
        function = getattr(stages, name)
        assert callable(function) and function is getattr(importlib.import_module(f"remaster.{module}"), attribute)
    assert set(api.__all__) <= set(dir(api)) and api.calibration.calibrate is api.calibrate
    with pytest.raises(AttributeError):
        stages.fit_everything  # noqa: B018
    with pytest.raises(AttributeError):
        api.calibrat  # noqa: B018


def _stages_called(source: str) -> list[str]:
    """The names of `api.stages.<name>` in `source`, in the order they appear."""
    return [
        node.attr
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Attribute)
        and node.value.attr == "stages"
        and isinstance(node.value.value, ast.Name)
        and node.value.value.id == "api"
    ]


def test_every_workflow_script_calls_one_stage_through_the_api():
    """Each script reads its inputs, calls one stage of `remaster.api.stages` and writes its outputs;
    every stage is some script's."""
    assert _stages_called("api.stages.close_loop(x, api.stages.build_report)\napi.settings()\n") == [
        "close_loop",
        "build_report",
    ]
    scripts = sorted((REPO / "workflow" / "scripts").glob("*.py"))
    called = {p.stem: _stages_called(p.read_text(encoding="utf-8")) for p in scripts}
    assert {s: c for s, c in called.items() if len(c) != 1} == {}, "a script calls exactly one stage"
    assert sorted(c for (c,) in called.values()) == sorted(stages.STAGES)


SIZES = {"optimization": {"poses": 16, "configurations": 80}, "validation": {"poses": 8, "configurations": 40}}
QUICK = {
    "loop_closure": {"residual_gp": {"enabled": False}},
    "accuracy": {"draws": 200, "random_configurations": 100},
    "acceptance": {"draws": 200},
    "comparison": {"random_configurations": 100, "draw_pairs": 20},
}


@pytest.fixture(scope="module")
def calibrations(tmp_path_factory):
    """Two campaigns of one simulated iiwa with rigid link errors (two seeds: new poses and noise),
    written as campaign folders and calibrated from them."""
    out = []
    for seed, date in ((23, "2024-01-10"), (24, "2024-06-10")):
        spec = iiwa_rigid_link_errors(seed=seed)
        spec["plan"]["sets"] = SIZES
        spec["name"], spec["date"] = f"iiwa-{seed}", date
        simulated = scenario.simulate(spec, chain_of(spec, REPO))
        folder = folders.write_campaign(
            tmp_path_factory.mktemp("raw") / spec["name"], simulated.metadata, simulated.tables
        )
        campaign = api.calibration.as_campaign(folder, REPO)
        out.append(api.calibrate(campaign, "laser_tracker", QUICK))
    return out


@pytest.mark.slow
def test_a_calibration_holds_the_pipelines_results(calibrations):
    calibration = calibrations[0]
    assert "link_geometry" in calibration.effects
    assert calibration.verdict in ("pass", "fail")
    assert calibration.verdict == calibration.acceptance.verdict
    report = calibration.loop.report
    assert report.validation_rmse_after_mm < report.validation_rmse_before_mm
    assert set(calibration.claims["model"]) == {"paper", "loop"}
    assert calibration.settings["accuracy"]["draws"] == 200
    assert calibration.workspace.report["draws"] == 200


@pytest.mark.slow
def test_predict_and_compensate_agree_with_each_other(calibrations):
    """What `predict` says the calibrated robot does at the commands `compensate` gives for targets
    is those targets; the commands are checked as `remaster predict` checks them."""
    calibration = calibrations[0]
    q = calibration.campaign.sensors["laser_tracker"].q("validation")[:4]
    predicted = api.predict(calibration, q, tcp=(0.0, 0.0, 0.1), draws=200)
    assert len(predicted) == 4 and (predicted["bound95_mm"] > 0).all()
    targets = predicted[["nominal_x", "nominal_y", "nominal_z"]].to_numpy()
    compensated = api.compensate(calibration, targets, tcp=(0.0, 0.0, 0.1), draws=200)
    reached = (compensated["status"] == "reached").to_numpy()
    assert reached.sum() >= 3 and (compensated.loc[~reached, "reason"].str.len() > 0).all()  # says why not
    commands = compensated.loc[reached, [f"q{j + 1}" for j in range(7)]].to_numpy()
    at = api.predict(calibration, commands, tcp=(0.0, 0.0, 0.1), draws=200)
    np.testing.assert_allclose(at[["x", "y", "z"]].to_numpy(), targets[reached], atol=1e-6)
    with pytest.raises(InputError, match="beyond the joint limits"):
        api.predict(calibration, np.full((1, 7), 4.0))
    with pytest.raises(ValueError, match="targets or commands"):
        api.compensate(calibration)


@pytest.mark.slow
def test_compare_gives_the_workflows_comparison_tables(calibrations):
    tables = api.compare(*calibrations, settings=QUICK)
    drift = tables["drift_between_campaigns"]
    assert set(drift["campaign_a"]) == {"iiwa-23"} and set(drift["campaign_b"]) == {"iiwa-24"}
    # the loop-closed model's parameters carry its MCMC refit's std (the zero-offset model at its
    # Laplace mode has none to compare: calibrate runs no paper sampler)
    loop = tables["loop_parameter_drift"]
    compared = loop[loop["status"] == "compared"]
    assert len(compared) and np.allclose(compared["z"], compared["diff"] / compared["combined_std"])
    predicted = tables["prediction_drift"]
    assert set(predicted["model"]) == {"paper", "loop"} and (predicted["mean_mm"] >= 0).all()
    assert len(tables["transfer"]) > 0
