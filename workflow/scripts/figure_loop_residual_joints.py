"""What the loop's parametric effects leave against the joint the residual GP finds most relevant."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures, figures_loop

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    figure = figures_loop.residual_by_joint(
        io.read_parquet(snakemake.input.gp), io.read_loop(snakemake.input.report).residual_gp,  # noqa: F821
        figures.sensor_title(w.campaign, w.sensor, "where the residual lives"))
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
