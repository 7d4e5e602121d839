# The HTML report: every table and figure of every campaign on one self-contained page, and the
# audit trail of the run.
from types import SimpleNamespace

REPORT_TABLES = ["zero_offsets", "registration_params", *TABLE_NAMES, "iso9283", "sensor_comparison", "loop_closure",
                 "loop_closure_test", "loop_candidates", "workspace_warnings", "workspace_accuracy",
                 "controller_offsets", "calibrated_files"]
REPORT_FIGURES = ["zero_offset_trace", "zero_offset_histograms", "tcp_scatter", "post_registration_histograms",
                  "loop_signatures", "loop_residuals", "loop_residual_joints", "workspace_accuracy"]


# the certificate's tables first, in the report's order
REPORT_CERTIFICATE_TABLES = [*CERTIFICATE_TABLES, "uncertainty_budget"]


def report_layout():
    """campaign -> summary, table and figure files, in the order the report shows them."""
    layout = {}
    for c in CAMPAIGNS:
        layout[c] = {
            "summary": f"{RESULTS}/{c}/campaign/summary.json",
            "certificate": f"{RESULTS}/{c}/certificate.json",
            "tables": {
                **{t: f"{RESULTS}/{c}/tables/{t}.csv" for t in REPORT_CERTIFICATE_TABLES},
                **{t: f"{RESULTS}/{c}/tables/{t}.csv" for t in REPORT_TABLES},
                **{f"{t}_vs_paper": f"{RESULTS}/{c}/tables/{t}_vs_paper.csv" for t in TABLE_NAMES
                   if c in config["paper_twins"]},
            },
            "figures": {
                **{f"{f}_{s}": f"{RESULTS}/{c}/figures/{f}_{s}.png" for f in REPORT_FIGURES for s in sensors_of(c)},
                "residuals": f"{RESULTS}/{c}/figures/residuals.png",
            },
        }
    return layout


def audited_results(campaign):
    """Every final result of a campaign: its tables, figures, fits, metrics and remastering files."""
    part = report_layout()[campaign]
    files = [part["summary"], part["certificate"], f"{RESULTS}/{campaign}/certificate.md", *part["tables"].values(),
             *part["figures"].values()]
    files += [str(Path(t).with_suffix(e)) for t in part["tables"].values() for e in (".md", ".tex")]
    files += [str(Path(f).with_suffix(".pdf")) for f in part["figures"].values()]
    for s in sensors_of(campaign):
        base = f"{RESULTS}/{campaign}/{s}"
        files += [f"{base}/remastering.json", f"{base}/registration.json", f"{base}/fit/summary.csv",
                  f"{base}/loop_closure.json", f"{base}/loop_closure/workspace.json",
                  f"{base}/loop_closure/residual_gp.parquet", f"{base}/fit/summary_discrepancy.csv",
                  *[f"{base}/calibrated/{name}" for name in CALIBRATED_FILES],
                  *[f"{base}/calibrated/{name}" for name in (CALIBRATED_DH_FILES if gives_dh(campaign) else ())],
                  f"{base}/fit/discrepancy.json",
                  f"{base}/loop_closure/workspace_accuracy.csv", f"{base}/loop_closure/theoretical_accuracy.csv",
                  f"{base}/fit/laplace.json", f"{base}/fit/cross_check.csv",
                  *[f"{base}/fit/samples_{m}.parquet" for m in FIT_METHODS],
                  *[f"{base}/metrics/{n}.csv" for n in ACCURACY_FILES]]
    return files


rule audit:
    input:
        campaigns=[f for c in CAMPAIGNS for f in campaign_files(SimpleNamespace(campaign=c))],
        results=[f for c in CAMPAIGNS for f in audited_results(c)],
    output:
        audit=f"{RESULTS}/audit.json",
    log:
        f"{RESULTS}/logs/audit.log",
    resources:
        mem_mb=1000,
        runtime=10,
    params:
        campaigns={c: campaign_files(SimpleNamespace(campaign=c)) for c in CAMPAIGNS},
        results={c: audited_results(c) for c in CAMPAIGNS},
        config=config,
    script:
        "../scripts/audit.py"


def comparison_layout():
    return {"tables": {t: f"{COMPARISON}/{t}.csv" for t in COMPARISON_TABLES},
            "figures": {f"{f}_{r}": f"{COMPARISON}/{f}_{r}.png" for f in OVER_TIME_FIGURES for r in ROBOTS}}


def prediction_layout():
    """The transfer table and the comparisons by prediction, with the transfer heat-maps."""
    return {"tables": {t: f"{COMPARISON}/{t}.csv" for t in PREDICTION_COMPARISON_TABLES},
            "figures": {f"transfer_{m}_{r}": f"{COMPARISON}/transfer_{m}_{r}.png" for m in TRANSFER_MODELS
                        for r in ROBOTS}}


def report_files(wildcards=None):
    files = []
    for part in [*report_layout().values(), comparison_layout(), prediction_layout()]:
        files += [*(part[k] for k in ("summary", "certificate") if k in part), *part["tables"].values(),
                  *part["figures"].values()]
    return files


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
    script:
        "../scripts/report.py"
