"""The calibrated DH tables (paper's and loop-closed model) of one sensor of a campaign given as a DH table."""

from remaster import io
from remaster.analysis import calibrated

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    i, out = snakemake.input, snakemake.output  # noqa: F821
    tables = calibrated.calibrated_dh_tables(io.read_campaign(io.campaign_folder(snakemake.input.campaign)), w.sensor,  # noqa: F821
                                             io.read_csv(i.summary), io.read_loop(i.loop), label=i.loop)
    io.write_yaml(out.paper, tables["paper"])
    io.write_yaml(out.loop, tables["loop"])
