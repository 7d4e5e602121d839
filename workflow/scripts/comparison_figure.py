"""Zero-offsets over time of one robot, every campaign and sensor."""

from pathlib import Path

from remaster import figures_comparison, io

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    identity = snakemake.params.identity  # noqa: F821
    table = io.read_csv(snakemake.input[0])  # noqa: F821
    figure = figures_comparison.zero_offsets_over_time_figure(table[table["robot"] == identity],
                                                              f"Zero-offsets over time: {identity}")
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
