"""One robot's parameters over time, every campaign and sensor: its zero-offsets, or the parameters
of the effects the loop closure added."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures_comparison

DRAW = {"zero_offsets_over_time": (figures_comparison.zero_offsets_over_time_figure, "Zero-offsets over time"),
        "loop_effects_over_time": (figures_comparison.loop_effects_over_time_figure, "Loop-closure effects over time")}

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    identity = snakemake.params.identity  # noqa: F821
    draw, title = DRAW[snakemake.params.figure]  # noqa: F821
    table = io.read_csv(snakemake.input[0])  # noqa: F821
    figure = draw(table[table["robot"] == identity], f"{title}: {identity}")
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
