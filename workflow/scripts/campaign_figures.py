"""The campaign's own figure: every sensor's residuals after remastering."""

from pathlib import Path

from snakemake.iocontainers import Snakemake

from remaster import api, files, stage_inputs

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

with files.log_to(snakemake.log[0]):
    errors = stage_inputs.by_sensor(dict(snakemake.input.items()), "configuration_errors")
    figure = api.stages.draw_campaign_figure(snakemake.wildcards.campaign, errors)
    files.write_figure(Path(snakemake.output.residuals[0]).with_suffix(""), figure)
