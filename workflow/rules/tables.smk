# Stage 6: every table of a campaign in one job (the paper's tables, the loop closure's, the
# workspace claims, the calibration's, the uncertainty budget and the certificate); the figures of
# each sensor in one job and the campaign's own figure in another (a rule's files cannot depend on
# how many sensors a campaign has). Tables and figures only read result files. The paper's twins
# (config paper_twins) also get each accuracy table beside the paper's published numbers: a
# second rule, because their set of files is larger; each campaign matches one of the two.
from remaster.layout import SENSOR_FIGURES

TABLES = f"{RESULTS}/{{campaign}}/tables"
FIGURES = f"{RESULTS}/{{campaign}}/figures"
PAPER_TWINS = [c for c in CAMPAIGNS if c in config["paper_twins"]]
CAMPAIGN_TABLES = [
    "zero_offsets",
    "registration_params",
    *TABLE_NAMES,
    "sensor_comparison",
    "iso9283",
    "iso9283_poses",
    "loop_closure",
    "loop_closure_test",
    "loop_candidates",
    "loop_harmonics_terms",
    "workspace_accuracy",
    "workspace_warnings",
    "controller_offsets",
    "calibrated_files",
    "uncertainty_budget",
]
CERTIFICATE_TABLES = ["certificate_verdict", "certificate_accuracy", "certificate_corrections"]


TABLE_INPUTS = dict(
    campaign=campaign_files,
    summary=rules.campaign_summary.output.summary,
)
SENSOR_TABLE_INPUTS = sensor_inputs(
    summary=f"{SENSOR}/{layout.SUMMARY}",
    laplace=f"{SENSOR}/{layout.LAPLACE}",
    registration=f"{SENSOR}/{layout.REGISTRATION}",
    configuration_errors=f"{ACC}/configuration_errors.csv",
    loop_theoretical=f"{LOOP}/theoretical_accuracy.csv",
    loop=f"{SENSOR}/{layout.LOOP_CLOSURE}",
    loop_table=f"{SENSOR}/{layout.LOOP_TABLE}",
    loop_residuals=f"{SENSOR}/{layout.LOOP_RESIDUALS}",
    claims=f"{LOOP}/workspace_accuracy.csv",
    workspace=f"{LOOP}/workspace.json",
    offsets=f"{CALIBRATED}/controller_offsets.csv",
    cross_check=f"{SENSOR}/{layout.CROSS_CHECK}",
    acceptance=f"{SENSOR}/{layout.ACCEPTANCE}",
    **{f"metrics_{t}": f"{ACC}/{t}.csv" for t in TABLE_NAMES},
)
TABLE_OUTPUTS = dict(
    certificate=f"{RESULTS}/{{campaign}}/certificate.md",
    record=f"{RESULTS}/{{campaign}}/certificate.json",
    **table_files(CAMPAIGN_TABLES + CERTIFICATE_TABLES),
)


rule tables:
    input:
        unpack(SENSOR_TABLE_INPUTS),
        unpack(calibrated_file_inputs),
        **TABLE_INPUTS,
    output:
        **TABLE_OUTPUTS,
    log:
        f"{RESULTS}/logs/{{campaign}}/tables.log",
    wildcard_constraints:
        campaign=f"(?!(?:{one_of(PAPER_TWINS)})/)[^/]+",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(1),
    params:
        beside_paper=False,
    script:
        "../scripts/tables.py"


rule tables_beside_paper:
    input:
        unpack(SENSOR_TABLE_INPUTS),
        unpack(calibrated_file_inputs),
        **TABLE_INPUTS,
    output:
        **TABLE_OUTPUTS,
        **table_files([f"{t}_vs_paper" for t in TABLE_NAMES]),
    log:
        f"{RESULTS}/logs/{{campaign}}/tables.log",
    wildcard_constraints:
        campaign=one_of(PAPER_TWINS),
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(1),
    params:
        beside_paper=True,
    script:
        "../scripts/tables.py"


rule figures:
    input:
        trace=f"{SENSOR}/{layout.TRACE.format(method='paper')}",
        samples=f"{SENSOR}/{layout.DEFAULT_SAMPLES}",
        tcp_scatter=f"{ACC}/tcp_scatter.csv",
        configuration_errors=f"{ACC}/configuration_errors.csv",
        signatures=f"{SENSOR}/{layout.LOOP_SIGNATURES}",
        loop_residuals=f"{SENSOR}/{layout.LOOP_RESIDUALS}",
        residual_gp=f"{SENSOR}/{layout.LOOP_GP}",
        loop=f"{SENSOR}/{layout.LOOP_CLOSURE}",
        claims=f"{LOOP}/workspace_accuracy.csv",
    output:
        **{name: multiext(f"{FIGURES}/{name}_{{sensor}}", ".png", ".pdf") for name in SENSOR_FIGURES},
    log:
        f"{RESULTS}/logs/{{campaign}}/{{sensor}}/figures.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=runtime_minutes(1),
    params:
        burn_in=config["fit"]["paper"]["burn_in"],
    script:
        "../scripts/figures.py"


rule campaign_figures:
    input:
        unpack(sensor_inputs(configuration_errors=f"{ACC}/configuration_errors.csv")),
    output:
        residuals=multiext(f"{FIGURES}/residuals", ".png", ".pdf"),
    log:
        f"{RESULTS}/logs/{{campaign}}/campaign_figures.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=5,
    script:
        "../scripts/campaign_figures.py"
