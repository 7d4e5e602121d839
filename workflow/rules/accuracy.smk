# Stage 3: accuracy metrics per campaign and sensor (relative, post-registration, theoretical,
# validation), the paper's accuracy tables, the sensor comparison and the accuracy figures.

from remaster.analysis.accuracy import METRIC_TABLES, TABLE_NAMES
from remaster.analysis.workspace import THEORETICAL_TABLES

ACC = f"{RESULTS}/{{campaign}}/{{sensor}}/metrics"
ACCURACY_FILES = list(TABLE_NAMES) + ["configuration_errors", "tcp_scatter", "remastering_parameters"]


rule accuracy:
    input:
        campaign=campaign_files,
        registration=rules.registration.output.registration,
        laplace=rules.laplace.output.laplace,
        samples=f"{RESULTS}/{{campaign}}/{{sensor}}/fit/samples_default.parquet",
        cross_check=rules.cross_check.output.table,  # only from samplers that agree
    output:
        **{name: f"{ACC}/{name}.csv" for name in ACCURACY_FILES},
        report=f"{ACC}/report.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/accuracy.log",
    params:
        names=ACCURACY_FILES,
        seed=config["seed"],
        draws=config["accuracy"]["draws"],
        random_configurations=config["accuracy"]["random_configurations"],
    script:
        "../scripts/accuracy.py"


for _table in TABLE_NAMES:

    rule:
        name:
            f"table_{_table}"
        input:
            metrics=per_sensor(f"{ACC}/{_table}.csv"),
            # the loop-closed model's rows (stage 4) beside the paper's, theoretical tables only
            loop=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/loop_closure/theoretical_accuracy.csv")
            if _table in THEORETICAL_TABLES else [],
        output:
            multiext(f"{TABLES}/{_table}", ".csv", ".md", ".tex"),
        log:
            f"{RESULTS}/logs/{{campaign}}/table_{_table}.log",
        params:
            sensors=lambda wc: sensors_of(wc.campaign),
            table=_table,
        script:
            "../scripts/table_accuracy.py"


rule table_vs_paper:
    input:
        f"{TABLES}/{{table}}.csv",
    output:
        multiext(f"{TABLES}/{{table}}_vs_paper", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_{{table}}_vs_paper.log",
    wildcard_constraints:
        table="|".join(TABLE_NAMES),
    script:
        "../scripts/table_vs_paper.py"


rule table_sensor_comparison:
    input:
        summaries=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/fit/summary.csv"),
        metrics=lambda wc: [f"{RESULTS}/{wc.campaign}/{s}/metrics/{t}.csv" for s in sensors_of(wc.campaign)
                            for t in TABLE_NAMES],
    output:
        multiext(f"{TABLES}/sensor_comparison", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_sensor_comparison.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
        tables=list(TABLE_NAMES),
    script:
        "../scripts/table_sensor_comparison.py"


rule table_iso9283:
    input:
        campaign=campaign_files,
        errors=per_sensor(f"{RESULTS}/{{campaign}}/{{sensor}}/metrics/configuration_errors.csv"),
    output:
        multiext(f"{TABLES}/iso9283", ".csv", ".md", ".tex"),
    log:
        f"{RESULTS}/logs/{{campaign}}/table_iso9283.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
    script:
        "../scripts/table_iso9283.py"


rule figure_tcp_scatter:
    input:
        f"{ACC}/tcp_scatter.csv",
    output:
        multiext(f"{FIGURES}/tcp_scatter_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_tcp_scatter.log",
    script:
        "../scripts/figure_tcp_scatter.py"


rule figure_post_registration_histograms:
    input:
        f"{ACC}/configuration_errors.csv",
    output:
        multiext(f"{FIGURES}/post_registration_histograms_{{sensor}}", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figure_post_registration_histograms.log",
    script:
        "../scripts/figure_post_registration_histograms.py"


rule figure_residuals:
    input:
        per_sensor(f"{ACC}/configuration_errors.csv"),
    output:
        multiext(f"{FIGURES}/residuals", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/figure_residuals.log",
    params:
        sensors=lambda wc: sensors_of(wc.campaign),
    script:
        "../scripts/figure_residuals.py"
