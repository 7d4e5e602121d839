"""Loop closure of one sensor: candidate effects scored, supported ones added, refit, before and after."""

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, seeding
from remaster.campaigns import folders
from remaster.loop import settings

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, i, p, out = snakemake.wildcards, snakemake.input, snakemake.params, snakemake.output
with files.log_to(snakemake.log[0]):
    result = api.stages.close_loop(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        w.sensor,
        results.read_result("registration", i.registration),
        results.read_result("laplace", i.laplace),
        seeding.generator(p.seed, w.campaign, w.sensor, "loop_closure"),
        settings.settings_from(p.settings, p.priors, p.convergence, p.outliers),
    )
    result.write(**{name: out[name] for name in ("report", "table", "signatures", "residuals", "samples", "gp")})
