"""Across campaigns, per robot: zero-offsets and loop-closure effects over time, and the transfer
heat-map of each model."""

from pathlib import Path

from snakemake.iocontainers import Snakemake

from remaster import api, files

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

with files.log_to(snakemake.log[0]):
    comparison_tables = {name: files.read_csv(path) for name, path in snakemake.input.items()}
    p = snakemake.params
    for stem, figure in api.stages.draw_comparison_figures(comparison_tables, dict(p.robots), p.models):
        files.write_figure(Path(snakemake.output[stem][0]).with_suffix(""), figure)
