"""results/report.html: every campaign's certificate, tables and figures, the comparisons across
campaigns and the audit trail, on one self-contained page."""

from pathlib import Path

from snakemake.iocontainers import Snakemake

from remaster import api, files
from remaster.comparing import predictions
from remaster.reporting import tables

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]


def read_part(part):
    """A layout part's files read: summary and certificate (JSON), tables (CSV), figures (PNG bytes)."""
    out = {key: files.read_json(part[key]) for key in ("summary", "certificate") if key in part}
    out["tables"] = {t: files.read_csv(path) for t, path in part["tables"].items()}
    out["figures"] = {f: Path(path).read_bytes() for f, path in part["figures"].items()}
    return out


with files.log_to(snakemake.log[0]):
    p = snakemake.params
    page = api.stages.build_report(
        {name: read_part(part) for name, part in p.layout.items()},
        {**tables.CAPTIONS, **predictions.CAPTIONS},
        audit=files.read_json(snakemake.input.audit),
        comparison=read_part(p.comparison),
        prediction=read_part(p.prediction),
        failed=dict(p.failed),
    )
    files.write_text(snakemake.output.html, page)
