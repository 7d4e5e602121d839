"""A campaign's table of calibrated files or of controller offsets, every sensor."""

from pathlib import Path

from remaster import io
from remaster.analysis import calibrated
from remaster.reporting import tables

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    p = snakemake.params  # noqa: F821
    if p.kind == "controller_offsets":
        table = calibrated.offsets_table({s: io.read_csv(f) for s, f in zip(p.sensors, snakemake.input)})  # noqa: F821
    else:
        table = calibrated.files_table(w.campaign, p.sensors, p.dh)
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, tables.CAPTIONS[p.kind], p.kind)  # noqa: F821
