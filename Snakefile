# remaster workflow: `snakemake -j2` rebuilds every result from the campaigns in data/raw.
# A job per campaign (or sensor) and stage; every rule is in one of the files included below.
configfile: "config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/campaign.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/loop_closure.smk"
include: "workflow/rules/acceptance.smk"
include: "workflow/rules/calibrated.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/comparison.smk"
include: "workflow/rules/report.smk"


# one writer per results folder: Snakemake locks the folder it runs in, not results_dir, which two
# checkouts may share (`remaster.results.take_lock`; a killed run's lock is taken over)
onstart:
    results.take_lock(RESULTS)
    RUN["started"] = time.time()


onsuccess:
    results.release_lock(RESULTS)


onerror:
    # a failed job's output is removed and the reports after it did not run: older ones would show
    # the numbers of results that are gone
    for stale in results.stale_reports(RESULTS, {c: sensors_of(c) for c in CAMPAIGNS}):
        stale.unlink()
        print(f"removed {stale}: a result it was made from failed in this run")
    results.release_lock(RESULTS)
    # the campaigns that did not fail still get the report and the comparison across campaigns
    # (common.smk: report_the_others); the failed ones are the report's red rows
    report_the_others(
        results.failed_campaigns(RESULTS, {c: audited_results(c) for c in CAMPAIGNS}, RUN.get("started", 0.0))
    )


rule all:
    default_target: True
    input:
        # the report reads every table and figure; its audit hashes every result file
        f"{RESULTS}/report.html",
