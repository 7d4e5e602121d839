"""Figure zero_offset_histograms: the posterior of every free zero-offset."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    figure = figures.zero_offset_histograms(io.read_parquet(snakemake.input.samples),  # noqa: F821
                                            figures.sensor_title(w.campaign, w.sensor, "zero-offset posterior"))
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
