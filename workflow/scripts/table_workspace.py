"""Where each calibration holds, every sensor of a campaign: the claims and the warnings."""

from pathlib import Path

from remaster import io
from remaster.analysis import workspace
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    p, i, out = snakemake.params, snakemake.input, snakemake.output  # noqa: F821
    claims = {s: io.read_csv(f) for s, f in zip(p.sensors, i.claims)}
    reports = {s: io.read_json(f) for s, f in zip(p.sensors, i.reports)}
    for name, files, table in (("workspace_accuracy", out.accuracy, workspace.workspace_table(claims, reports)),
                               ("workspace_warnings", out.warnings, workspace.warnings_table(reports))):
        io.write_table(Path(files[0]).with_suffix(""), table, tables.CAPTIONS[name], name)
