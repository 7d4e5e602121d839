# The HTML report: every table and figure of every campaign on one self-contained page, and the
# audit trail of the run.
from types import SimpleNamespace

REPORT_TABLES = [
    "zero_offsets",
    "registration_params",
    *TABLE_NAMES,
    "iso9283",
    "iso9283_poses",
    "sensor_comparison",
    "loop_closure",
    "loop_closure_test",
    "loop_candidates",
    "loop_harmonics_terms",
    "workspace_warnings",
    "workspace_accuracy",
    "controller_offsets",
    "calibrated_files",
]


# the certificate's tables first, in the report's order
REPORT_CERTIFICATE_TABLES = [*CERTIFICATE_TABLES, "uncertainty_budget"]


rule audit:
    input:
        campaigns=[f for c in CAMPAIGNS for f in campaign_files(SimpleNamespace(campaign=c))],
        results=[f for c in CAMPAIGNS for f in audited_results(c)],
    output:
        audit=f"{RESULTS}/{layout.AUDIT}",
    log:
        f"{RESULTS}/logs/audit.log",
    resources:
        mem_mb=1000,
        runtime=10,
    params:
        results={c: audited_results(c) for c in CAMPAIGNS},
        config=config,
    script:
        "../scripts/audit.py"


rule report:
    input:
        report_files,
        audit=rules.audit.output.audit,
    output:
        html=f"{RESULTS}/report.html",
    log:
        f"{RESULTS}/logs/report.log",
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        layout=report_layout(),
        comparison=comparison_layout(),
        prediction=prediction_layout(),
        failed=config["failed_campaigns"],
    script:
        "../scripts/report.py"
