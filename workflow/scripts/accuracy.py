"""Every accuracy metric of one sensor: Vernier and Bayesian, optimization and validation sets."""

from remaster import io, seeding
from remaster.analysis import accuracy

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    p = snakemake.params  # noqa: F821
    results = accuracy.accuracy_tables(
        io.read_campaign(io.campaign_folder(snakemake.input.campaign)), w.sensor, io.read_registration(snakemake.input.registration),  # noqa: F821
        io.read_laplace(snakemake.input.laplace), io.read_parquet(snakemake.input.samples),  # noqa: F821
        seeding.generator(p.seed, w.campaign, w.sensor, "accuracy"), n_draws=p.draws, n_random=p.random_configurations)
    for name in p.names:
        io.write_csv(snakemake.output[name], results[name])  # noqa: F821
    io.write_json(snakemake.output.report, results["report"])  # noqa: F821
