"""Residuals of the Bayesian fit against configuration and distance from the base, every sensor."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures_accuracy

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    errors = {s: io.read_csv(p) for s, p in zip(snakemake.params.sensors, snakemake.input)}  # noqa: F821
    figure = figures_accuracy.residual_plots(errors, f"{snakemake.wildcards.campaign}: residuals after remastering")  # noqa: F821
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
