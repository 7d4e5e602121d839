"""Read and validate one campaign folder; write its summary."""

from remaster import io
from remaster.campaigns import campaign

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    data = io.read_campaign(io.campaign_folder(snakemake.input.campaign))  # noqa: F821
    p = snakemake.params  # noqa: F821
    io.write_json(snakemake.output.summary, campaign.summarize(data, p.memory_limit, p.draws))  # noqa: F821
