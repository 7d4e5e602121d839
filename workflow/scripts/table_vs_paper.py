"""An accuracy table of a twin of the paper's experiment beside the paper's published numbers."""

from pathlib import Path

from remaster import io
from remaster.analysis import accuracy
from remaster.reporting import tables

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    table = accuracy.paper_comparison(w.table, io.read_csv(snakemake.input[0]))  # noqa: F821
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table,  # noqa: F821
                   tables.CAPTIONS[w.table] + " Beside the paper's published values.", f"{w.table}_vs_paper")
