"""The workflow's stages, one function each: what each script of workflow/scripts/ calls, between
reading its inputs and writing its outputs. In the pipeline's order:

    summarize_campaign          a campaign folder read, checked and summarized (summary.json)
    register_and_fit_laplace    one sensor's initial registration, outlier screen and the zero-offset
                                (paper) model's Laplace fit (registration.json, fit/laplace.json)
    sample_posterior            every sampling method's posterior samples, trace and diagnostics
    summarize_fit               the samplers cross-checked, the posterior summary, the discrepancy,
                                the remastering and the accuracy metrics
    close_loop                  the loop closure: candidate effects scored, supported ones added, refit
    run_acceptance_test         both models tested on the validation set: a verdict and a diagnosis
    make_calibrated_outputs     the workspace claims, calibrated URDFs, effects, controller offsets
                                (and DH tables, a UR's kinematics_configs)
    draw_sensor_figures         every figure of one sensor
    make_campaign_tables        every table of one campaign, and its certificate
    draw_campaign_figure        the campaign's residuals after remastering, every sensor
    compare_campaigns           zero-offsets and loop-closure parameters over time, drift, agreement
    compare_predictions         the same by predicted marker positions, and the transfer table
    draw_comparison_figures     the cross-campaign figures of each robot
    make_audit_record           results/audit.json: the hashes of campaigns, config, code and results
    build_report                results/report.html: every result on one self-contained page

    from remaster import api

    registration, laplace = api.stages.register_and_fit_laplace(campaign, "laser_tracker", config["outliers"])

Each workflow job is a fresh Python process, and the stages' modules are heavy (SciPy, Numba,
Matplotlib): a name is imported from its module on first use only (then kept here), so that a job
loads its own stage's modules and no other's.
"""

from __future__ import annotations

import importlib

# {name: (module below remaster, the function's name there)}, in the pipeline's order
STAGES = {
    "summarize_campaign": ("campaigns.folders", "summarize_folder"),
    "register_and_fit_laplace": ("inference.fit", "prepare_stage"),
    "sample_posterior": ("inference.fit", "sampling_stage"),
    "summarize_fit": ("evaluation.fit_summary", "fit_summary_stage"),
    "close_loop": ("loop.loop_closure", "loop_closure_stage"),
    "run_acceptance_test": ("evaluation.acceptance", "acceptance_stage"),
    "make_calibrated_outputs": ("evaluation.handover", "calibrated_outputs_stage"),
    "draw_sensor_figures": ("reporting.campaign_figures", "sensor_figures"),
    "make_campaign_tables": ("reporting.campaign_tables", "campaign_tables"),
    "draw_campaign_figure": ("reporting.campaign_figures", "campaign_figure"),
    "compare_campaigns": ("comparing.comparison", "comparison_tables"),
    "compare_predictions": ("comparing.transfer", "prediction_stage"),
    "draw_comparison_figures": ("reporting.figures_comparison", "comparison_figures"),
    "make_audit_record": ("audit", "audit_record"),
    "build_report": ("reporting.report", "build"),
}

__all__ = list(STAGES)


def __getattr__(name: str):
    if name not in STAGES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = STAGES[name]
    value = getattr(importlib.import_module(f"remaster.{module}"), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
