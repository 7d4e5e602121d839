# The HTML report: every table and figure of every campaign on one self-contained page.

REPORT_TABLES = ["zero_offsets", "registration_params", *TABLE_NAMES, "sensor_comparison"]
REPORT_FIGURES = ["zero_offset_trace", "zero_offset_histograms", "tcp_scatter", "post_registration_histograms"]


def report_layout():
    """campaign -> summary, table and figure files, in the order the report shows them."""
    layout = {}
    for c in CAMPAIGNS:
        layout[c] = {
            "summary": f"{RESULTS}/{c}/campaign/summary.json",
            "tables": {
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


def report_files(wildcards=None):
    files = []
    for part in report_layout().values():
        files += [part["summary"], *part["tables"].values(), *part["figures"].values()]
    return files


rule report:
    input:
        report_files,
    output:
        html=f"{RESULTS}/report.html",
    log:
        f"{RESULTS}/logs/report.log",
    params:
        layout=report_layout(),
    script:
        "../scripts/report.py"
