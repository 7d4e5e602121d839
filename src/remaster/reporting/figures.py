"""The paper's figures (and a few more), drawn from result files only.

Every function takes DataFrames or arrays and returns a matplotlib Figure (Agg backend, no
screen); `remaster.files.write_figure` saves it as PNG and PDF. Units on the axes are mm and deg.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ..labels import sensor_label  # noqa: E402
from ..units import DEG  # noqa: E402


def _zero_offset_columns(samples: pd.DataFrame) -> list[str]:
    return [c for c in samples.columns if c.startswith("zero_offsets.")]


def _grid(count: int, panel_width: float = 3.2, panel_height: float = 2.4, max_columns: int = 4):
    """Up to `max_columns` panels a row, each `panel_width` by `panel_height` inches; the unused
    ones hidden."""
    columns = min(max_columns, count)
    rows = int(np.ceil(count / columns))
    fig, axes = plt.subplots(rows, columns, figsize=(panel_width * columns, panel_height * rows), squeeze=False)
    for ax in axes.flat[count:]:
        ax.set_visible(False)
    return fig, axes.flat


def error_histogram_axes(ax, title: str) -> None:
    """Titles, labels and legend of a histogram of post-registration errors (mm)."""
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("post-registration error (mm)", fontsize=8)
    ax.set_ylabel("configurations", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7)


def finished(fig, title: str):
    """The figure with its title, laid out."""
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def note(text: str, title: str) -> plt.Figure:
    """A figure that says why there is nothing to draw: a figure of nothing is a sentence, never an
    error of the plotting."""
    fig, ax = plt.subplots(figsize=(6.0, 3.0))
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, wrap=True)
    ax.set_axis_off()
    return finished(fig, title)


# every zero-offset held (a robot with one joint, or joints whose axes coincide): the fit has none
NO_FREE_ZERO_OFFSET = "no free zero-offset: the data determine none (fit/laplace.json says which are held and why)"


def zero_offset_trace(trace: pd.DataFrame, burn_in: int, title: str) -> plt.Figure:
    """Fig. zero_offset_trace: each free zero-offset (deg) against the step, one line per chain,
    with the burn-in boundary. `trace` has step and chain columns and one column per parameter (SI)."""
    columns = _zero_offset_columns(trace)
    if not columns:
        return note(NO_FREE_ZERO_OFFSET, title)
    fig, axes = _grid(len(columns))
    for ax, name in zip(axes, columns):
        for number, chain in trace.groupby("chain"):
            ax.plot(chain["step"] / 1e3, chain[name] / DEG, lw=0.6, label=f"chain {number + 1}")
        ax.axvline(burn_in / 1e3, color="tab:red", lw=0.8, ls="--")
        ax.set_title(name.replace("zero_offsets.", "zero-offset "), fontsize=9)
        ax.set_xlabel("step (thousands)", fontsize=8)
        ax.set_ylabel("deg", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def zero_offset_histograms(samples: pd.DataFrame, title: str, truth_deg: dict[str, float] | None = None) -> plt.Figure:
    """Fig. zero_offset_histograms: the posterior of each free zero-offset (deg), with its
    mean; `truth_deg` (simulations only, never read by the pipeline itself) may mark the truth."""
    columns = _zero_offset_columns(samples)
    if not columns:
        return note(NO_FREE_ZERO_OFFSET, title)
    fig, axes = _grid(len(columns))
    for ax, name in zip(axes, columns):
        values = samples[name].to_numpy() / DEG
        ax.hist(values, bins=40, color="tab:blue", alpha=0.8)
        ax.axvline(values.mean(), color="k", lw=1.0)
        if truth_deg and name in truth_deg:
            ax.axvline(truth_deg[name], color="tab:green", lw=1.0, ls="--")
        ax.set_title(name.replace("zero_offsets.", "zero-offset "), fontsize=9)
        ax.set_xlabel("deg", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def sensor_title(campaign: str, sensor: str, what: str) -> str:
    return f"{campaign}, {sensor_label(sensor)}: {what}"
