"""Across campaigns: zero-offsets and loop-closure parameters over time, their drift between
campaigns of one robot, and the sensors' agreement."""

from pathlib import Path

from snakemake.iocontainers import Snakemake

from remaster import api, files, results, stage_inputs
from remaster.reporting import tables

# The job (input, output, params, wildcards, log) that Snakemake's script directive defines before
# this file runs; named here so that readers and linters see where it comes from.
snakemake: Snakemake = globals()["snakemake"]

with files.log_to(snakemake.log[0]):
    named = dict(snakemake.input.items())
    result = api.stages.compare_campaigns(
        {c: files.read_yaml(f) for c, f in stage_inputs.by_sensor(named, "metadata").items()},
        {pair: results.read_result("summary", f) for pair, f in stage_inputs.by_pair(named, "summary").items()},
        {pair: results.read_result("loop", f) for pair, f in stage_inputs.by_pair(named, "loop").items()},
        snakemake.params.significance,
    )
    for name, table in result.items():
        tables.write_table(Path(snakemake.output[name][0]).with_suffix(""), table, tables.CAPTIONS[name], name)
