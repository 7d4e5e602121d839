"""Posterior samples of every sampling method for one sensor (expensive: plotting reads the files)."""

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, seeding
from remaster.campaigns import folders

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, i, out = snakemake.wildcards, snakemake.input, snakemake.output
settings = dict(snakemake.params.settings)
with files.log_to(snakemake.log[0]) as log:
    methods = api.stages.sample_posterior(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        w.sensor,
        results.read_result("registration", i.registration),
        results.read_result("laplace", i.laplace),
        settings,
        {method: seeding.generator(snakemake.params.seed, w.campaign, w.sensor, method) for method in settings},
        progress=lambda method, step, total, rate: log.info(
            "%s: step %d of %d, acceptance %.3f", method, step, total, rate
        ),
    )
    for method, (samples, trace, diagnostics) in methods.items():
        files.write_parquet(out[f"samples__{method}"], samples)
        files.write_parquet(out[f"trace__{method}"], trace)
        files.write_json(out[f"diagnostics__{method}"], diagnostics)
