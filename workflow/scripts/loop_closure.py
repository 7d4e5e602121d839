"""Loop closure of one sensor: candidate effects scored, supported ones added, refit, before and after."""

import pandas as pd

from remaster import io, seeding
from remaster.loop import loop_closure

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    p, out = snakemake.params, snakemake.output  # noqa: F821
    result = loop_closure.loop_closure_stage(
        io.read_campaign(io.campaign_folder(snakemake.input.campaign)), w.sensor, io.read_registration(snakemake.input.registration),  # noqa: F821
        io.read_laplace(snakemake.input.laplace), seeding.generator(p.seed, w.campaign, w.sensor, "loop_closure"),  # noqa: F821
        loop_closure.settings_from(p.settings, p.priors, p.convergence))
    io.write_json(out.report, result.report)
    io.write_csv(out.table, result.table)
    io.write_parquet(out.signatures, loop_closure.signatures_frame(result.signatures))
    io.write_parquet(out.residuals, loop_closure.residuals_frame(result.residuals, result.rows))
    io.write_parquet(out.samples, result.samples if result.samples is not None else pd.DataFrame())
    io.write_parquet(out.gp, result.gp)
