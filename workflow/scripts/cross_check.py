"""Every method's posterior mean and std side by side; fails if converged methods disagree."""

from remaster import io
from remaster.inference import fit

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    methods = snakemake.params.methods  # noqa: F821
    samples = {m: io.read_parquet(p) for m, p in zip(methods, snakemake.input.samples)}  # noqa: F821
    reports = {m: io.read_json(p) for m, p in zip(methods, snakemake.input.diagnostics)}  # noqa: F821
    table = fit.cross_check(samples, reports, io.read_laplace(snakemake.input.laplace), **snakemake.params.settings)  # noqa: F821
    io.write_csv(snakemake.output.table, table)  # noqa: F821
