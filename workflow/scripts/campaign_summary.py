"""Read and validate one campaign folder; write its summary."""

from snakemake.iocontainers import Snakemake

from remaster import api, files
from remaster.campaigns import folders

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

with files.log_to(snakemake.log[0]):
    p = snakemake.params
    summary = api.stages.summarize_campaign(
        folders.campaign_folder(snakemake.input.campaign), p.memory_limit, p.draws, p.fit_rows
    )
    files.write_json(snakemake.output.summary, summary)
