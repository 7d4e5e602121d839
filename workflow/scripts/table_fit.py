"""Table MLE_zero_offsets or MLE_other_params of one campaign, every sensor side by side."""

from pathlib import Path

from remaster import io
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    kind = snakemake.params.kind  # noqa: F821
    summaries = {s: io.read_csv(p) for s, p in zip(snakemake.params.sensors, snakemake.input.summaries)}  # noqa: F821
    if kind == "registration_params":  # it also says how many points each fit used and left out
        fits = {s: io.read_laplace(p) for s, p in zip(snakemake.params.sensors, snakemake.input.laplace)}  # noqa: F821
        table = tables.registration_params_table(summaries, fits)
    else:
        table = tables.zero_offsets_table(summaries)
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, tables.CAPTIONS[kind], kind)  # noqa: F821
