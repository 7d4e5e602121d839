"""The loop-closed model's theoretical accuracy and where each calibration holds, one sensor."""

from remaster import io, seeding
from remaster.analysis import comparison, workspace

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    p, i, out = snakemake.params, snakemake.input, snakemake.output  # noqa: F821
    campaign = io.read_campaign(io.campaign_folder(snakemake.input.campaign))
    result = workspace.workspace_accuracy(
        campaign.chain, campaign.sensors[w.sensor], comparison.robot_identity(campaign), io.read_csv(i.summary),
        io.read_laplace(i.laplace), io.read_loop(i.report), io.read_parquet(i.samples),
        seeding.generator(p.seed, w.campaign, w.sensor, "workspace"), n_draws=p.draws,
        n_random=p.random_configurations, seed=p.seed, label=i.samples, loop_gp_rows=io.read_parquet(i.gp))
    io.write_csv(out.theoretical, result.theoretical)
    io.write_csv(out.claims, result.claims)
    io.write_json(out.report, result.report)
