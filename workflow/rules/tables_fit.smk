# Tables and figures of the fit (paper: tables MLE_zero_offsets and MLE_other_params, figures
# zero_offset_trace and zero_offset_histograms). Plotting and tabulating only read result files.

TABLES = f"{RESULTS}/{{campaign}}/tables"
FIGURES = f"{RESULTS}/{{campaign}}/figures"


rule table_zero_offsets:
    input:
        summaries=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv"),
    output:
        multiext(f"{TABLES}/zero_offsets", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_zero_offsets.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="zero_offsets",
    script:
        "../scripts/table_fit.py"


rule table_registration_params:
    input:
        summaries=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv"),
        laplace=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/laplace.json"),
    output:
        multiext(f"{TABLES}/registration_params", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_registration_params.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        kind="registration_params",
    script:
        "../scripts/table_fit.py"


rule figure_zero_offset_trace:
    input:
        trace=f"{RESULTS}/{{campaign}}/{{sensor}}/fit/trace_paper.parquet",
    output:
        multiext(f"{FIGURES}/zero_offset_trace_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_zero_offset_trace.log",
    params:
        burn_in=config["fit"]["paper"]["burn_in"],
    script:
        "../scripts/figure_zero_offset_trace.py"


rule figure_zero_offset_histograms:
    input:
        samples=f"{RESULTS}/{{campaign}}/{{sensor}}/fit/samples_default.parquet",
    output:
        multiext(f"{FIGURES}/zero_offset_histograms_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_zero_offset_histograms.log",
    script:
        "../scripts/figure_zero_offset_histograms.py"
