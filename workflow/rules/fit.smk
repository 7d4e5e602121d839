# Stage 2: per campaign and sensor, the registration and Laplace fit (prepare), one job per sampler
# (the expensive, parallel part), then the samplers' cross-check, the posterior summary, the model
# discrepancy, the remastering file and the accuracy metrics of the paper's tables (paper, sections
# Optimization, Quantifying Positional Accuracy and Validation).
from remaster.analysis.accuracy import TABLE_NAMES

FIT = f"{RESULTS}/{{campaign}}/{{sensor}}/fit"
ACC = f"{RESULTS}/{{campaign}}/{{sensor}}/metrics"
ACCURACY_FILES = list(TABLE_NAMES) + ["configuration_errors", "tcp_scatter", "remastering_parameters"]


rule prepare:
    input:
        campaign=campaign_files,
        # the campaign's check comes first: one too large for the memory a job may use stops here
        summary=f"{RESULTS}/{{campaign}}/campaign/summary.json",
    output:
        registration=f"{RESULTS}/{{campaign}}/{{sensor}}/registration.json",
        laplace=f"{FIT}/laplace.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/prepare.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(1),
    params:
        outlier_alpha=config["outliers"]["alpha"],
    script:
        "../scripts/prepare.py"


rule sample:
    input:
        campaign=campaign_files,
        registration=rules.prepare.output.registration,
        laplace=rules.prepare.output.laplace,
    output:
        samples=f"{FIT}/samples_{{method}}.parquet",
        trace=f"{FIT}/trace_{{method}}.parquet",
        diagnostics=f"{FIT}/diagnostics_{{method}}.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/sample_{{method}}.log",
    wildcard_constraints:
        method="|".join(FIT_METHODS),
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(10, at_least=15),
    params:
        settings=lambda wc: config["fit"][wc.method],
        seed=config["seed"],
    script:
        "../scripts/sample.py"


rule fit_summary:
    input:
        **{f"samples__{m}": f"{FIT}/samples_{m}.parquet" for m in FIT_METHODS},
        **{f"diagnostics__{m}": f"{FIT}/diagnostics_{m}.json" for m in FIT_METHODS},
        campaign=campaign_files,
        registration=rules.prepare.output.registration,
        laplace=rules.prepare.output.laplace,
    output:
        **{f"metrics__{name}": f"{ACC}/{name}.csv" for name in ACCURACY_FILES},
        cross_check=f"{FIT}/cross_check.csv",
        summary=f"{FIT}/summary.csv",
        with_discrepancy=f"{FIT}/summary_discrepancy.csv",
        discrepancy=f"{FIT}/discrepancy.json",
        remastering=f"{RESULTS}/{{campaign}}/{{sensor}}/remastering.json",
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
