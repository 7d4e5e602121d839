"""The residual against each candidate effect's signature (first round of the loop)."""

from pathlib import Path

from remaster import io
from remaster.loop import loop_closure
from remaster.reporting import figures, figures_loop

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    candidates = loop_closure.signatures_of_round(io.read_parquet(snakemake.input[0]), 1)  # noqa: F821
    figure = figures_loop.signatures(candidates, figures.sensor_title(w.campaign, w.sensor, "residual vs candidate effects"))
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
