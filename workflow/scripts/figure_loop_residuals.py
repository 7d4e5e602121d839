"""Post-registration errors before and after the loop closure, per set."""

from pathlib import Path

from remaster import io
from remaster.loop import loop_closure
from remaster.reporting import figures, figures_loop

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    residuals = loop_closure.residuals_of(io.read_parquet(snakemake.input[0]))  # noqa: F821
    figure = figures_loop.residual_histograms(residuals, figures.sensor_title(w.campaign, w.sensor, "before and after the loop"))
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
