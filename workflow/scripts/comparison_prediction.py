"""Across campaigns, by what calibrations predict: each calibration on the other campaigns of its
robot (transfer), drift and agreement as the change of predicted marker positions."""

from pathlib import Path

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, stage_inputs
from remaster.calibration import prediction
from remaster.campaigns import folders
from remaster.comparing import predictions
from remaster.reporting import tables

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

i, p = snakemake.input, snakemake.params
with files.log_to(snakemake.log[0]):
    named = dict(i.items())

    def each(kind):
        return {pair: results.read_result(kind, f) for pair, f in stage_inputs.by_pair(named, kind).items()}

    result = api.stages.compare_predictions(
        {c: folders.read_campaign(f) for c, f in folders.campaign_folders(i.campaigns).items()},
        each("summary"),
        each("laplace"),
        each("loop"),
        each("paper_samples"),
        each("loop_samples"),
        prediction.Propagation(p.draw_pairs, p.random_configurations, p.seed),
    )
    for name, table in result.items():
        stem = Path(snakemake.output[name][0]).with_suffix("")
        tables.write_table(stem, table, predictions.CAPTIONS[name], name)
