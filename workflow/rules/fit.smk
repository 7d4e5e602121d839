# Stage 2: per campaign and sensor, the registration and Laplace fit (prepare), the three samplers
# (the expensive part; one job, so that the model is built and the libraries loaded once), then the
# samplers' cross-check, the posterior summary, the model discrepancy, the remastering file and the
# accuracy metrics of the paper's tables (paper, sections Optimization, Quantifying Positional
# Accuracy and Validation).
from remaster.evaluation.accuracy import TABLE_NAMES

ACC = f"{SENSOR}/{layout.METRICS}"
ACCURACY_FILES = list(TABLE_NAMES) + ["configuration_errors", "tcp_scatter", "remastering_parameters"]


rule prepare:
    input:
        campaign=campaign_files,
        # the campaign's check comes first: one too large for the memory a job may use stops here
        summary=f"{RESULTS}/{{campaign}}/campaign/summary.json",
    output:
        registration=f"{SENSOR}/{layout.REGISTRATION}",
        laplace=f"{SENSOR}/{layout.LAPLACE}",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/prepare.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(1),
    params:
        outliers=config["outliers"],
    script:
        "../scripts/prepare.py"


rule sample:
    input:
        campaign=campaign_files,
        registration=rules.prepare.output.registration,
        laplace=rules.prepare.output.laplace,
    output:
        **{f"samples__{m}": f"{SENSOR}/{layout.SAMPLES.format(method=m)}" for m in FIT_METHODS},
        **{f"trace__{m}": f"{SENSOR}/{layout.TRACE.format(method=m)}" for m in FIT_METHODS},
        **{f"diagnostics__{m}": f"{SENSOR}/{layout.DIAGNOSTICS.format(method=m)}" for m in FIT_METHODS},
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/sample.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(30, at_least=45),
    params:
        # emcee and the default sampler run until the cross-check's convergence criteria hold (fit/<method>/max_doublings)
        settings={m: {**config["fit"][m], "convergence": config["fit"]["cross_check"]} for m in FIT_METHODS},
        seed=config["seed"],
    script:
        "../scripts/sample.py"


rule fit_summary:
    input:
        **{f"samples__{m}": f"{SENSOR}/{layout.SAMPLES.format(method=m)}" for m in FIT_METHODS},
        **{f"diagnostics__{m}": f"{SENSOR}/{layout.DIAGNOSTICS.format(method=m)}" for m in FIT_METHODS},
        campaign=campaign_files,
        registration=rules.prepare.output.registration,
        laplace=rules.prepare.output.laplace,
    output:
        **{f"metrics__{name}": f"{ACC}/{name}.csv" for name in ACCURACY_FILES},
        cross_check=f"{SENSOR}/{layout.CROSS_CHECK}",
        summary=f"{SENSOR}/{layout.SUMMARY}",
        with_discrepancy=f"{SENSOR}/{layout.SUMMARY_DISCREPANCY}",
        discrepancy=f"{SENSOR}/{layout.DISCREPANCY}",
        remastering=f"{SENSOR}/{layout.REMASTERING}",
        accuracy=f"{ACC}/report.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/fit_summary.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(2, at_least=10),
    params:
        cross_check=config["fit"]["cross_check"],
        seed=config["seed"],
        draws=config["accuracy"]["draws"],
        random_configurations=config["accuracy"]["random_configurations"],
    script:
        "../scripts/fit_summary.py"
