"""Claimed error of the paper's and the loop-closed model, measured and random configurations."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures, figures_loop

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    figure = figures_loop.workspace_claims(io.read_csv(snakemake.input[0]),  # noqa: F821
                                           figures.sensor_title(w.campaign, w.sensor, "where the calibration holds"))
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
