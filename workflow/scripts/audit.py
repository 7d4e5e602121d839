"""results/audit.json: per campaign the content hash (robot description included), the config, the
code's hash, the seed and every result's hash."""

from snakemake.iocontainers import Snakemake

from remaster import api, files, provenance
from remaster.campaigns import folders

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

with files.log_to(snakemake.log[0]):
    p = snakemake.params
    campaigns = folders.campaign_folders(snakemake.input.campaigns)
    record = api.stages.make_audit_record(
        # the digests `remaster predict` and `compensate` compute again to check a campaign is unchanged
        {c: folders.campaign_digests(folder) for c, folder in campaigns.items()},
        {c: provenance.file_digests(paths) for c, paths in p.results.items()},
        dict(p.config),
        provenance.package_digests(),
        provenance.git_commit(),
        {c: folders.outside_inputs(folder) for c, folder in campaigns.items()},
    )
    files.write_json(snakemake.output.audit, record)
