"""Figure accuracy: Vernier, MLE, probable and probable-plus-noise TCPs of one configuration."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures, figures_accuracy

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    figure = figures_accuracy.tcp_scatter(io.read_csv(snakemake.input[0]),  # noqa: F821
                                          figures.sensor_title(w.campaign, w.sensor, "TCPs of one configuration"))
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
