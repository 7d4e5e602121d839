"""Every table of one campaign, and its certificate."""

from pathlib import Path

from snakemake.iocontainers import Snakemake

from remaster import api, files, stage_inputs
from remaster.campaigns import folders
from remaster.reporting import campaign_tables, certificate, tables

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

i, out = snakemake.input, snakemake.output
with files.log_to(snakemake.log[0]):
    result = api.stages.make_campaign_tables(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        snakemake.wildcards.campaign,
        files.read_json(i.summary),
        stage_inputs.by_kind(dict(i.items())),
        beside_paper=snakemake.params.beside_paper,
    )
    for table in result.tables:
        tables.write_table(Path(out[table.name][0]).with_suffix(""), table.frame, table.caption, table.name)
    files.write_json(out.record, campaign_tables.certificate_record(result.certificate))
    files.write_text(out.certificate, certificate.to_markdown(result.certificate))
