"""The uncertainty budget of a campaign, every sensor (GUM style)."""

from pathlib import Path

from remaster import io
from remaster.analysis import budget
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    i, sensors = snakemake.input, snakemake.params.sensors  # noqa: F821
    table = budget.budget_table(io.read_campaign(io.campaign_folder(snakemake.input.campaign)),  # noqa: F821
                                dict(zip(sensors, map(io.read_registration, i.registration))),
                                dict(zip(sensors, map(io.read_laplace, i.laplace))),
                                dict(zip(sensors, map(io.read_loop, i.loop))))
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, tables.CAPTIONS["uncertainty_budget"],  # noqa: F821
                   "uncertainty_budget")
