# Stage 2: per campaign and sensor, registration, identifiability + least squares, samplers,
# their cross-check, the posterior summary and the remastering file (paper, section Optimization).

FIT = f"{RESULTS}/{{campaign}}/{{sensor}}/fit"


rule registration:
    input:
        campaign=campaign_files,
        # the campaign's check comes first: one too large for the memory a job may use stops here
        summary=f"{RESULTS}/{{campaign}}/campaign/summary.json",
    output:
        registration=f"{RESULTS}/{{campaign}}/{{sensor}}/registration.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/registration.log",
    script:
        "../scripts/registration.py"


rule laplace:
    input:
        campaign=campaign_files,
        registration=rules.registration.output.registration,
    output:
        laplace=f"{FIT}/laplace.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/laplace.log",
    params:
        outlier_alpha=config["outliers"]["alpha"],
    script:
        "../scripts/laplace.py"


rule sample:
    input:
        campaign=campaign_files,
        registration=rules.registration.output.registration,
        laplace=rules.laplace.output.laplace,
    output:
        samples=f"{FIT}/samples_{{method}}.parquet",
        trace=f"{FIT}/trace_{{method}}.parquet",
        diagnostics=f"{FIT}/diagnostics_{{method}}.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/sample_{{method}}.log",
    wildcard_constraints:
        method="|".join(FIT_METHODS),
    params:
        settings=lambda wc: config["fit"][wc.method],
        seed=config["seed"],
    script:
        "../scripts/sample.py"


rule cross_check:
    input:
        samples=expand(f"{FIT}/samples_{{method}}.parquet", method=FIT_METHODS, allow_missing=True),
        diagnostics=expand(f"{FIT}/diagnostics_{{method}}.json", method=FIT_METHODS, allow_missing=True),
        laplace=rules.laplace.output.laplace,
    output:
        table=f"{FIT}/cross_check.csv",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/cross_check.log",
    params:
        methods=FIT_METHODS,
        settings=config["fit"]["cross_check"],
    script:
        "../scripts/cross_check.py"


rule posterior_summary:
    input:
        samples=f"{FIT}/samples_default.parquet",
        laplace=rules.laplace.output.laplace,
        cross_check=rules.cross_check.output.table,  # no summary of samplers that disagree
    output:
        summary=f"{FIT}/summary.csv",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/posterior_summary.log",
    script:
        "../scripts/posterior_summary.py"


rule discrepancy:
    input:
        campaign=campaign_files,
        registration=rules.registration.output.registration,
        laplace=rules.laplace.output.laplace,
        summary=rules.posterior_summary.output.summary,
    output:
        summary=f"{FIT}/summary_discrepancy.csv",
        report=f"{FIT}/discrepancy.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/discrepancy.log",
    script:
        "../scripts/discrepancy.py"


rule remastering:
    input:
        campaign=campaign_files,
        summary=rules.posterior_summary.output.summary,
    output:
        remastering=f"{RESULTS}/{{campaign}}/{{sensor}}/remastering.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/remastering.log",
    script:
        "../scripts/remastering.py"
