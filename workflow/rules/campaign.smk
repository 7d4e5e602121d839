# Stage 1: read and validate each campaign; summarize what it holds (rows, sets, missing points).


rule campaign_summary:
    input:
        campaign=campaign_files,
    output:
        summary=f"{RESULTS}/{{campaign}}/campaign/summary.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/campaign_summary.log",
    resources:
        mem_mb=campaign_mem_mb,
        runtime=5,
    params:
        memory_limit=JOB_MEMORY_LIMIT,
        draws=config["accuracy"]["draws"],
        fit_rows=config["loop_closure"]["fit_rows"],
    script:
        "../scripts/campaign_summary.py"
