"""One cross-campaign table (`remaster.analysis.comparison.TABLES`): zero-offsets or loop-closure parameters over
time, their drift between campaigns, or the sensors' agreement."""

from pathlib import Path

from remaster import io
from remaster.analysis import comparison
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    p = snakemake.params  # noqa: F821
    metadata = {c: io.read_yaml(f) for c, f in zip(p.campaigns, snakemake.input.metadata)}  # noqa: F821
    summaries = {tuple(pair): io.read_csv(f) for pair, f in zip(p.pairs, snakemake.input.summaries)}  # noqa: F821
    loops = {tuple(pair): io.read_loop(f) for pair, f in zip(p.pairs, snakemake.input.loops)}  # noqa: F821
    table = comparison.table(p.table, comparison.entries_of(metadata, summaries, loops), p.significance)
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, tables.CAPTIONS[p.table], p.table)  # noqa: F821
