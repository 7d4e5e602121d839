"""Loop-closure table of a campaign: before and after per sensor, the closure test, or every candidate's scores."""

from pathlib import Path

from remaster import io
from remaster.loop import loop_closure
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    p = snakemake.params  # noqa: F821
    reports = {s: io.read_json(f) for s, f in zip(p.sensors, snakemake.input.reports)}  # noqa: F821
    if p.kind == "loop_closure":
        befores = {s: io.read_csv(f) for s, f in zip(p.sensors, snakemake.input.tables)}  # noqa: F821
        table = loop_closure.campaign_table(befores, reports)
    elif p.kind == "loop_closure_test":
        table = loop_closure.closure_table(reports)
    else:
        table = loop_closure.candidates_table(reports)
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, tables.CAPTIONS[p.kind], p.kind)  # noqa: F821
