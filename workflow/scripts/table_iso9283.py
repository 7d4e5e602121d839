"""ISO 9283 pose characteristics (AP, and RP where configurations repeat) of a campaign, every sensor."""

from pathlib import Path

from remaster import io
from remaster.analysis import iso9283
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    campaign = io.read_campaign(io.campaign_folder(snakemake.input.campaign))  # noqa: F821
    sensors = snakemake.params.sensors  # noqa: F821
    table = iso9283.iso9283_table({s: campaign.sensors[s] for s in sensors},
                                  {s: io.read_csv(p) for s, p in zip(sensors, snakemake.input.errors)})  # noqa: F821
    io.write_table(Path(snakemake.output[0]).with_suffix(""), table, tables.CAPTIONS["iso9283"], "iso9283")  # noqa: F821
