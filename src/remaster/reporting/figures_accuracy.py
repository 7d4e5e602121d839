"""Accuracy figures, drawn from the tables `remaster.evaluation.accuracy.accuracy_tables` returns.

Every function returns a matplotlib Figure (Agg backend); `remaster.files.write_figure` saves it.
Axes are in mm.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ..labels import paper_order, sensor_label  # noqa: E402
from .figures import error_histogram_axes, finished  # noqa: E402

# fig. accuracy's colours, drawn widest cloud first so that every kind stays visible
TCP_STYLE = {
    "probable + noise": ("tab:blue", 4, 0.35),
    "probable": ("gold", 4, 0.6),
    "MLE": ("tab:green", 60, 1.0),
    "Vernier": ("tab:red", 60, 1.0),
}
METHOD_COLOURS = {"Vernier": "tab:red", "Bayesian": "tab:green"}  # a registration variant of Vernier is not drawn
COMPONENT_COLOURS = {"x": "tab:blue", "y": "tab:orange", "z": "tab:purple"}


def tcp_scatter(scatter: pd.DataFrame, title: str) -> plt.Figure:
    """Fig. accuracy: TCPs of one configuration in X-Y (mm, relative to the MLE TCP): Vernier red,
    MLE green, probable TCPs (posterior draws) yellow, probable with the Gaussian error blue.
    `scatter` has columns kind, x_mm, y_mm (the stage's "tcp_scatter")."""
    fig, ax = plt.subplots(figsize=(5.0, 4.6))
    for kind, (colour, size, alpha) in TCP_STYLE.items():
        points = scatter[scatter["kind"] == kind]
        if len(points):
            ax.scatter(
                points["x_mm"],
                points["y_mm"],
                s=size,
                color=colour,
                alpha=alpha,
                lw=0,
                label=f"{kind} TCP" if kind in ("MLE", "Vernier") else f"{kind} TCPs",
            )
    ax.set_xlabel("X (mm, from the MLE TCP)")
    ax.set_ylabel("Y (mm, from the MLE TCP)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="best")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def post_registration_histograms(errors: pd.DataFrame, title: str, registration: str | None = None) -> plt.Figure:
    """Post-registration errors ||E_i|| (mm), Vernier against Bayesian, one panel per set.

    `errors` is the stage's "configuration_errors" (set, registration, method, error_mm); with
    several registrations in a set, `registration` picks one (default: the first listed)."""
    sets = list(dict.fromkeys(errors["set"]))
    fig, axes = plt.subplots(1, max(len(sets), 1), figsize=(4.2 * max(len(sets), 1), 3.2), squeeze=False)
    for ax, set_name in zip(axes.flat, sets):
        part = errors[errors["set"] == set_name]
        chosen = registration if registration in set(part["registration"]) else part["registration"].iloc[0]
        part = part[part["registration"] == chosen]
        bins = np.histogram_bin_edges(part["error_mm"], bins=30)
        for method, colour in METHOD_COLOURS.items():
            values = part.loc[part["method"] == method, "error_mm"]
            if len(values):
                ax.hist(values, bins=bins, color=colour, alpha=0.55, label=f"{method} (mean {values.mean():.2f} mm)")
        error_histogram_axes(ax, f"{set_name} set")
    return finished(fig, title)


def residual_plots(
    errors: dict[str, pd.DataFrame], title: str, method: str = "Bayesian", set_name: str = "optimization"
) -> plt.Figure:
    """Residual components (measured - predicted, sensor frame, mm) against the configuration
    index and against the marker's distance from the robot base, one row per sensor.

    errors: sensor -> the stage's "configuration_errors"; the rows of `method` on `set_name`
    with the optimization set's registration are drawn."""
    sensors = paper_order(errors)
    fig, axes = plt.subplots(len(sensors), 2, figsize=(9.0, 2.8 * len(sensors)), squeeze=False)
    for row, sensor in zip(axes, sensors):
        frame = errors[sensor]
        part = frame[(frame["method"] == method) & (frame["set"] == set_name)]
        if len(part):
            part = part[part["registration"] == part["registration"].iloc[0]]
        for ax, abscissa, label in (
            (row[0], "configuration", "configuration index"),
            (row[1], "distance_from_base_mm", "distance from base (mm)"),
        ):
            for component, colour in COMPONENT_COLOURS.items():
                ax.scatter(
                    part[abscissa],
                    part[f"residual_{component}_mm"],
                    s=6,
                    color=colour,
                    alpha=0.7,
                    lw=0,
                    label=component,
                )
            ax.axhline(0.0, color="k", lw=0.6)
            ax.set_xlabel(label, fontsize=8)
            ax.set_ylabel(f"{sensor_label(sensor)} residual (mm)", fontsize=8)
            ax.tick_params(labelsize=7)
        row[0].legend(fontsize=7, markerscale=2)
    fig.suptitle(f"{title} ({method}, {set_name} set)", fontsize=10)
    fig.tight_layout()
    return fig
