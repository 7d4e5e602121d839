"""One of the paper's accuracy tables for a campaign: Vernier, Bayesian (and Loop-closed), every sensor."""

from pathlib import Path

from remaster import io
from remaster.analysis import accuracy, workspace
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    name = snakemake.params.table  # noqa: F821
    sensors, i = snakemake.params.sensors, snakemake.input  # noqa: F821
    per_sensor = {s: io.read_csv(p) for s, p in zip(sensors, i.metrics)}
    for s, p in zip(sensors, i.loop):  # the loop-closed model's rows, theoretical tables only
        per_sensor[s] = workspace.with_loop_rows(per_sensor[s], io.read_csv(p), name)
    io.write_table(Path(snakemake.output[0]).with_suffix(""), accuracy.paper_table(per_sensor),  # noqa: F821
                   tables.CAPTIONS[name], name)
