"""Every figure of one sensor of a campaign, each drawn once and saved as PNG and PDF."""

from pathlib import Path

from snakemake.iocontainers import Snakemake

from remaster import api, files

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, out = snakemake.wildcards, snakemake.output
with files.log_to(snakemake.log[0]):
    inputs = {name: str(path) for name, path in snakemake.input.items()}
    for name, figure in api.stages.draw_sensor_figures(w.campaign, w.sensor, inputs, snakemake.params.burn_in):
        files.write_figure(Path(out[name][0]).with_suffix(""), figure)
