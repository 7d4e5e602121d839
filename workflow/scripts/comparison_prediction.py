"""Drift between campaigns or the sensors' agreement as the change of predicted marker positions."""

from pathlib import Path

from remaster import io
from remaster.analysis import prediction

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    p, i = snakemake.params, snakemake.input  # noqa: F821
    pairs = [tuple(pair) for pair in p.pairs]

    def each(read, files):
        return {pair: read(f) for pair, f in zip(pairs, files)}

    table = prediction.prediction_table(
        p.table, {c: io.read_campaign(f) for c, f in io.campaign_folders(i.campaigns).items()}, each(io.read_csv, i.summaries),
        each(io.read_laplace, i.laplaces), each(io.read_loop, i.loops), each(io.read_parquet, i.paper_samples),
        each(io.read_parquet, i.loop_samples), n_configurations=p.random_configurations, seed=p.seed,
        draw_pairs=p.draw_pairs)
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, prediction.CAPTIONS[p.table], p.table)  # noqa: F821
