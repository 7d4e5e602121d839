"""The new zero-offsets (deg) with their uncertainty, ready to type into the controller."""

from remaster import io
from remaster.inference import fit

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    campaign = io.read_campaign(io.campaign_folder(snakemake.input.campaign))  # noqa: F821
    summary = io.read_csv(snakemake.input.summary)  # noqa: F821
    io.write_json(snakemake.output.remastering, fit.remastering(summary, campaign.chain.joint_names, w.campaign, w.sensor))  # noqa: F821
