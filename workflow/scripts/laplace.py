"""Outlier screening, identifiability analysis and least-squares/Laplace fit of one sensor."""

from remaster import io
from remaster.inference import fit

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    campaign = io.read_campaign(io.campaign_folder(snakemake.input.campaign))  # noqa: F821
    registration = io.read_registration(snakemake.input.registration)  # noqa: F821
    io.write_json(snakemake.output.laplace,  # noqa: F821
                  fit.laplace_stage(campaign, snakemake.wildcards.sensor, registration,  # noqa: F821
                                    snakemake.params.outlier_alpha))  # noqa: F821
