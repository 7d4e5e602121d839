"""One sensor's fit once its samplers have run: cross-check, posterior summary, discrepancy,
remastering and the accuracy metrics."""

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, seeding, stage_inputs
from remaster.campaigns import folders
from remaster.evaluation import fit_summary

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

w, i, out, p = snakemake.wildcards, snakemake.input, snakemake.output, snakemake.params
with files.log_to(snakemake.log[0]):
    named = dict(i.items())
    result = api.stages.summarize_fit(
        folders.read_campaign(folders.campaign_folder(i.campaign)),
        w.sensor,
        results.read_result("registration", i.registration),
        results.read_result("laplace", i.laplace),
        {m: results.read_result("samples", f) for m, f in stage_inputs.by_sensor(named, "samples").items()},
        {m: results.read_result("diagnostics", f) for m, f in stage_inputs.by_sensor(named, "diagnostics").items()},
        seeding.generator(p.seed, w.campaign, w.sensor, "accuracy"),
        fit_summary.SummarySettings(dict(p.cross_check), p.draws, p.random_configurations),
    )
    files.write_csv(out.cross_check, result.cross_check)
    files.write_csv(out.summary, result.summary)
    files.write_csv(out.with_discrepancy, result.with_discrepancy)
    files.write_json(out.discrepancy, result.discrepancy)
    files.write_json(out.remastering, result.remastering)
    for name, path in stage_inputs.by_sensor(dict(out.items()), "metrics").items():
        files.write_csv(path, result.accuracy[name])
    files.write_json(out.accuracy, result.accuracy["report"])
