"""Each campaign's calibration applied to every campaign of the same robot and sensor (transfer table)."""

from pathlib import Path

from remaster import io
from remaster.analysis import prediction, transfer

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    p, i = snakemake.params, snakemake.input  # noqa: F821
    pairs = [tuple(pair) for pair in p.pairs]
    table = transfer.transfer_stage({c: io.read_campaign(f) for c, f in io.campaign_folders(i.campaigns).items()},
                                    {pair: io.read_csv(f) for pair, f in zip(pairs, i.summaries)},
                                    {pair: io.read_laplace(f) for pair, f in zip(pairs, i.laplaces)},
                                    {pair: io.read_loop(f) for pair, f in zip(pairs, i.loops)})
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, prediction.CAPTIONS["transfer"],  # noqa: F821
                   "transfer")
