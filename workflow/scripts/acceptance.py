"""The validation set as the acceptance test of one sensor: both models checked, a verdict, a diagnosis."""

from snakemake.iocontainers import Snakemake

from remaster import files, seeding
from remaster.campaigns import folders
from remaster.evaluation import acceptance
from remaster.inference import fit
from remaster.loop.result import LoopReport, LoopResults

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, i, p, out = snakemake.wildcards, snakemake.input, snakemake.params, snakemake.output
with files.log_to(snakemake.log[0]):
    result = acceptance.acceptance_stage(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        w.sensor,
        fit.Registration.read(i.registration).t_nr,
        fit.LaplaceReport.read(i.laplace),
        files.read_parquet(i.paper_samples),
        LoopResults(
            LoopReport.read(i.loop), files.read_parquet(i.loop_samples), files.read_parquet(i.gp), i.loop_samples
        ),
        seeding.generator(p.seed, w.campaign, w.sensor, "acceptance"),
        p.settings,
    )
    result.write(out.report)
