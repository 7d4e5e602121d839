# Stage 1: read and validate each campaign; summarize what it holds (rows, sets, missing points).


rule campaign_summary:
    input:
        campaign_files,
    output:
        summary=f"{RESULTS}/{{campaign}}/campaign/summary.json",
    log:
        f"{RESULTS}/logs/{{campaign}}/campaign_summary.log",
    params:
        folder=lambda wc: f"{RAW}/{wc.campaign}",
        memory_limit=None if config["max_job_memory_gb"] is None else config["max_job_memory_gb"] * 1e9,
        draws=config["accuracy"]["draws"],
    script:
        "../scripts/campaign_summary.py"
