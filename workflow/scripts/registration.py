"""Initial three-point registration of one sensor (with a Kabsch comparison)."""

from remaster import io
from remaster.inference import fit

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    campaign = io.read_campaign(io.campaign_folder(snakemake.input.campaign))  # noqa: F821
    io.write_json(snakemake.output.registration, fit.registration_stage(campaign, snakemake.wildcards.sensor).report())  # noqa: F821
