"""The sensors of a campaign side by side: estimates, their differences in combined uncertainty, accuracy."""

from pathlib import Path

from remaster import io
from remaster.analysis import accuracy
from remaster.reporting import tables

with io.log_to(snakemake.log[0]):  # noqa: F821 (snakemake injects it)
    sensors, names = snakemake.params.sensors, snakemake.params.tables  # noqa: F821
    summaries = {s: io.read_csv(p) for s, p in zip(sensors, snakemake.input.summaries)}  # noqa: F821
    metrics = iter(snakemake.input.metrics)  # noqa: F821  (sensor-major, table-minor)
    per_sensor = {s: {t: io.read_csv(next(metrics)) for t in names} for s in sensors}
    io.write_table(Path(snakemake.output[0]).with_suffix(""), accuracy.sensor_comparison(summaries, per_sensor),  # noqa: F821
                   tables.CAPTIONS["sensor_comparison"], "sensor_comparison")
