"""The validation set as the acceptance test of one sensor: both models checked, a verdict, a diagnosis."""

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, seeding
from remaster.campaigns import folders
from remaster.loop.result import LoopResults

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, i, p, out = snakemake.wildcards, snakemake.input, snakemake.params, snakemake.output
with files.log_to(snakemake.log[0]):
    read = results.read_results(
        dict(i.items()), ("registration", "laplace", "paper_samples", "loop", "loop_samples", "gp")
    )
    result = api.stages.run_acceptance_test(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        w.sensor,
        read["registration"].t_nr,
        read["laplace"],
        read["paper_samples"],
        LoopResults(read["loop"], read["loop_samples"], read["gp"], i.loop_samples),
        seeding.generator(p.seed, w.campaign, w.sensor, "acceptance"),
        p.settings,
    )
    result.write(out.report)
