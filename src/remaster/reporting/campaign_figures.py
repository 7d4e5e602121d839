"""The figures of one sensor of a campaign, and the campaign's own figure: each drawn once (the
writer saves it as PNG and PDF), one at a time, so only one figure is open at once.

Figures only read result files: `files` maps a kind of result file to its path. Kinds: trace
(fit/trace_paper.parquet), samples (fit/samples_default.parquet), tcp_scatter and
configuration_errors (metrics/), signatures, loop_residuals, residual_gp (loop_closure/), loop
(loop_closure.json), claims (loop_closure/workspace_accuracy.csv).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import matplotlib.pyplot as plt

from .. import files as result_files
from ..loop import long_tables
from ..loop.result import LoopReport
from . import figures, figures_accuracy, figures_loop


def sensor_figures(
    campaign: str, sensor: str, files: Mapping[str, str], burn_in: int
) -> Iterator[tuple[str, plt.Figure]]:
    """(figure name, figure) for every figure of one sensor (`layout.SENSOR_FIGURES`, in order); `campaign`:
    its folder name (titles); `burn_in`: the paper sampler's, marked on its trace."""

    def title(what: str) -> str:
        return figures.sensor_title(campaign, sensor, what)

    yield (
        "zero_offset_trace",
        figures.zero_offset_trace(result_files.read_parquet(files["trace"]), burn_in, title("paper Metropolis trace")),
    )
    yield (
        "zero_offset_histograms",
        figures.zero_offset_histograms(result_files.read_parquet(files["samples"]), title("zero-offset posterior")),
    )
    yield (
        "tcp_scatter",
        figures_accuracy.tcp_scatter(result_files.read_csv(files["tcp_scatter"]), title("TCPs of one configuration")),
    )
    yield (
        "post_registration_histograms",
        figures_accuracy.post_registration_histograms(
            result_files.read_csv(files["configuration_errors"]), title("post-registration error")
        ),
    )
    yield (
        "loop_signatures",
        figures_loop.signatures(
            long_tables.signatures_of_round(result_files.read_parquet(files["signatures"]), 1),
            title("residual vs candidate effects"),
        ),
    )
    yield (
        "loop_residuals",
        figures_loop.residual_histograms(
            long_tables.residuals_of(result_files.read_parquet(files["loop_residuals"])),
            title("before and after the loop"),
        ),
    )
    yield (
        "loop_residual_joints",
        figures_loop.residual_by_joint(
            result_files.read_parquet(files["residual_gp"]),
            LoopReport.read(files["loop"]).residual_gp,
            title("where the residual lives"),
        ),
    )
    yield (
        "loop_harmonics",
        figures_loop.harmonic_functions(LoopReport.read(files["loop"]).harmonics, title("joints' cyclic errors")),
    )
    yield (
        "workspace_accuracy",
        figures_loop.workspace_claims(result_files.read_csv(files["claims"]), title("where the calibration holds")),
    )


def campaign_figure(campaign: str, configuration_errors: Mapping[str, str]) -> plt.Figure:
    """The campaign's residuals after remastering, every sensor (`configuration_errors`: sensor ->
    metrics/configuration_errors.csv)."""
    errors = {s: result_files.read_csv(p) for s, p in configuration_errors.items()}
    return figures_accuracy.residual_plots(errors, f"{campaign}: residuals after remastering")
