"""results/audit.json: per campaign the content hash (robot description included), the config, the code's hash, the seed and every result's hash."""

from remaster import audit, io

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    p = snakemake.params  # noqa: F821
    record = audit.audit_record({c: io.file_digests(files, relative_to_parent=True) for c, files in p.campaigns.items()},
                                {c: io.file_digests(files) for c, files in p.results.items()}, dict(p.config),
                                io.package_digests(), io.git_commit())
    io.write_json(snakemake.output.audit, record)  # noqa: F821
