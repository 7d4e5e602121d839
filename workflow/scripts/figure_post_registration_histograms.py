"""Post-registration errors, Vernier against Bayesian, per set."""

from pathlib import Path

from remaster import io
from remaster.reporting import figures, figures_accuracy

w = snakemake.wildcards  # noqa: F821 (snakemake injects it)
with io.log_to(snakemake.log[0]):  # noqa: F821
    figure = figures_accuracy.post_registration_histograms(
        io.read_csv(snakemake.input[0]), figures.sensor_title(w.campaign, w.sensor, "post-registration error"))  # noqa: F821
    io.write_figure(Path(snakemake.output[0]).with_suffix(""), figure)  # noqa: F821
