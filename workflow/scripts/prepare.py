"""Registration and Laplace fit of one sensor: registration.json and fit/laplace.json."""

from snakemake.iocontainers import Snakemake

from remaster import api, files
from remaster.campaigns import folders

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

with files.log_to(snakemake.log[0]):
    campaign = folders.read_campaign(folders.campaign_folder(snakemake.input.campaign))
    registration, laplace = api.stages.register_and_fit_laplace(
        campaign, snakemake.wildcards.sensor, snakemake.params.outliers
    )
    files.write_json(snakemake.output.registration, registration)
    files.write_json(snakemake.output.laplace, laplace)
