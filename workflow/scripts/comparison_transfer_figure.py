"""Heat-map of one robot's transfer table for one model (validation RMSE, calibrated on x evaluated on)."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures_comparison

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    p = snakemake.params  # noqa: F821
    table = io.read_csv(snakemake.input[0])  # noqa: F821
    figure = figures_comparison.transfer_figure(table[(table["robot"] == p.identity) & (table["model"] == p.model)],
                                                f"Transfer, {p.model} model: {p.identity}")
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
