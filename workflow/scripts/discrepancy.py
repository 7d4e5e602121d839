"""The paper's fit of one sensor with stds that include what the model lacks, for the comparison across campaigns."""

from remaster import io
from remaster.inference import discrepancy

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    i, out = snakemake.input, snakemake.output  # noqa: F821
    summary, report = discrepancy.discrepancy_stage(
        io.read_campaign(io.campaign_folder(snakemake.input.campaign)), w.sensor, io.read_registration(i.registration),  # noqa: F821
        io.read_laplace(i.laplace), io.read_csv(i.summary))
    io.write_csv(out.summary, summary)
    io.write_json(out.report, report)
