"""Posterior samples of one sampling method for one sensor (expensive: plotting reads the file)."""

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, seeding
from remaster.campaigns import folders

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, i, out = snakemake.wildcards, snakemake.input, snakemake.output
with files.log_to(snakemake.log[0]) as log:
    samples, trace, diagnostics = api.stages.sample_posterior(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        w.sensor,
        results.read_result("registration", i.registration),
        results.read_result("laplace", i.laplace),
        w.method,
        dict(snakemake.params.settings),
        seeding.generator(snakemake.params.seed, w.campaign, w.sensor, w.method),
        progress=lambda step, total, rate: log.info("%s: step %d of %d, acceptance %.3f", w.method, step, total, rate),
    )
    files.write_parquet(out.samples, samples)
    files.write_parquet(out.trace, trace)
    files.write_json(out.diagnostics, diagnostics)
