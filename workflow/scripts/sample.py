"""Posterior samples of one sampling method for one sensor (expensive: plotting reads the file)."""

from remaster import io, seeding
from remaster.inference import fit

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]) as log:  # noqa: F821
    campaign = io.read_campaign(io.campaign_folder(snakemake.input.campaign))  # noqa: F821
    samples, trace, diagnostics = fit.sampling_stage(
        campaign, w.sensor, io.read_registration(snakemake.input.registration), io.read_laplace(snakemake.input.laplace),  # noqa: F821
        w.method, dict(snakemake.params.settings),  # noqa: F821
        seeding.generator(snakemake.params.seed, w.campaign, w.sensor, w.method),  # noqa: F821
        progress=lambda step, total, rate: log.info("%s: step %d of %d, acceptance %.3f", w.method, step, total, rate))
    io.write_parquet(snakemake.output.samples, samples)  # noqa: F821
    io.write_parquet(snakemake.output.trace, trace)  # noqa: F821
    io.write_json(snakemake.output.diagnostics, diagnostics)  # noqa: F821
