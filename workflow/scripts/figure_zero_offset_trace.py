"""Figure zero_offset_trace: the paper sampler's zero-offset chains over the whole run."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    figure = figures.zero_offset_trace(io.read_parquet(snakemake.input.trace), snakemake.params.burn_in,  # noqa: F821
                                       figures.sensor_title(w.campaign, w.sensor, "paper Metropolis trace"))
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
