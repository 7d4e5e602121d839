"""MLE (posterior mean), std and 95 % interval of every parameter of one sensor."""

from remaster import io
from remaster.inference import fit

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    summary = fit.posterior_summary(io.read_parquet(snakemake.input.samples), io.read_laplace(snakemake.input.laplace))  # noqa: F821
    io.write_csv(snakemake.output.summary, summary.reset_index())  # noqa: F821
