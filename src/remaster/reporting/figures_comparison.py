"""Figures across campaigns, drawn from `remaster.comparing.comparison` tables (Agg backend, deg on the axes)."""

from __future__ import annotations

import textwrap
from collections.abc import Iterable, Iterator, Mapping

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .. import layout  # noqa: E402
from ..inference.parameter_blocks import EXTENSIONS  # noqa: E402
from ..labels import paper_order, sensor_label  # noqa: E402
from .figures import _grid  # noqa: E402

MARKERS = "osD^v<>"
MAX_LABELS = 24  # campaign labels on the x axis; beyond that, every k-th campaign is named


def _one_robot(table: pd.DataFrame) -> None:
    robots = sorted(table["robot"].unique())
    if len(robots) > 1:
        raise ValueError(f"rows of {len(robots)} robots ({', '.join(map(repr, robots))}): draw one robot at a time")


def _campaign_axis(campaigns: pd.DataFrame) -> tuple[list[int], list[str]]:
    """Tick positions and labels ('<campaign>\\n<date>') of campaigns in date order, one slot each:
    every campaign when there are at most MAX_LABELS, else every k-th, first and last included."""
    step = max(1, int(np.ceil(len(campaigns) / MAX_LABELS)))
    last = len(campaigns) - 1
    shown = list(range(0, last - step + 1, step)) + [last]  # the last a full step from the one before
    return shown, [f"{campaigns['campaign'].iloc[i]}\n{campaigns['date'].iloc[i]}" for i in shown]


def _over_time(
    table: pd.DataFrame, title: str, parameters: list[str], mean: str, std: str, units: dict[str, str], label
) -> plt.Figure:
    """One panel per parameter: `mean` of each campaign, in date order (one slot per campaign, so
    campaigns of one day stay apart; the dates are in the labels), one series per sensor with
    +-`std` bars (open markers, no bar, where not estimated); y label from `units`, panel title
    `label(parameter)`."""
    sensors = paper_order(table["sensor"].unique())
    campaigns = table[["date", "campaign"]].drop_duplicates().sort_values(["date", "campaign"], ignore_index=True)
    slot = pd.Series(np.arange(len(campaigns)), index=campaigns["campaign"])
    offsets = {s: (i - (len(sensors) - 1) / 2) * 0.5 / len(sensors) for i, s in enumerate(sensors)}
    ticks, tick_labels = _campaign_axis(campaigns)
    many = len(campaigns) > 6  # labels turned upright so they do not overlap

    if many:  # wider panels, two a row, room below each for the upright labels
        fig, axes = _grid(len(parameters), panel_width=max(3.2, 0.12 * len(campaigns)), panel_height=3.8, max_columns=2)
    else:
        fig, axes = _grid(len(parameters))
    axes = list(axes)[: len(parameters)]
    for ax, name in zip(axes, parameters):
        for i, sensor in enumerate(sensors):
            rows = table[(table["parameter"] == name) & (table["sensor"] == sensor)]
            x = rows["campaign"].map(slot).to_numpy(dtype=float) + offsets[sensor]
            estimated = (rows["status"] == "estimated").to_numpy()
            color, marker = f"C{i}", MARKERS[i % len(MARKERS)]
            ax.errorbar(
                x[estimated],
                rows[mean][estimated],
                yerr=rows[std][estimated],
                fmt=marker,
                color=color,
                ms=4,
                capsize=2,
                lw=0.8,
                label=sensor_label(sensor),
            )
            if (~estimated).any():
                ax.plot(
                    x[~estimated],
                    rows[mean][~estimated],
                    marker,
                    mfc="none",
                    color=color,
                    ms=5,
                    label=f"{sensor_label(sensor)} (held)",
                )
        ax.set_xticks(ticks, tick_labels, fontsize=6, rotation=90 if many else 0)
        ax.set_xlim(-0.6, len(campaigns) - 0.4)
        ax.set_title(label(name), fontsize=9)
        ax.set_ylabel(units[name], fontsize=8)
        ax.tick_params(axis="y", labelsize=7)
    legend = {}
    for ax in axes:
        for handle, text in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(text, handle)
    fig.suptitle(f"{title} (bars: +-1 std)", fontsize=10)
    # 0.3 in at the bottom for the legend, 0.3 in at the top for the title
    fig.tight_layout(rect=(0, 0.3 / fig.get_figheight(), 1, 1 - 0.3 / fig.get_figheight()))
    fig.legend(list(legend.values()), list(legend), fontsize=7, loc="lower center", ncols=len(legend), frameon=False)
    return fig


def zero_offsets_over_time_figure(table: pd.DataFrame, title: str) -> plt.Figure:
    """Each zero-offset (deg) against the campaign date, one panel per joint, one series per sensor
    with +-1 std error bars; a held parameter is an open marker at its held value, without a bar.

    `table`: `comparison.zero_offsets_over_time` rows of one robot (ValueError otherwise). Sensors
    of one campaign are drawn side by side, a little apart in time, so their bars do not overlap.
    """
    if table.empty:
        raise ValueError("no zero-offsets to draw")
    _one_robot(table)
    parameters = sorted(table["parameter"].unique(), key=lambda n: int(n.rsplit("q", 1)[1]))
    return _over_time(
        table,
        title,
        parameters,
        "mean_deg",
        "std_deg",
        dict.fromkeys(parameters, "deg"),
        lambda name: name.replace("zero_offsets.", "zero-offset "),
    )


def loop_effects_over_time_figure(table: pd.DataFrame, title: str) -> plt.Figure:
    """The parameters of the effects the loop closure added (zero-offsets left out: they have
    their own figure), each in its display unit against the campaign date, drawn as
    `zero_offsets_over_time_figure` draws; blocks in `parameter_blocks.EXTENSIONS` order, parameters in
    model order within a block. With no effect added in any
    campaign, a figure that says so.

    `table`: `comparison.loop_parameters_over_time` rows of one robot (ValueError otherwise).
    """
    _one_robot(table)
    effects = table[table["block"] != "zero_offsets"]
    estimated = effects.loc[effects["status"] == "estimated", "parameter"]
    effects = effects[effects["parameter"].isin(estimated)]
    if effects.empty:
        fig, ax = plt.subplots(figsize=(6.4, 1.2))
        ax.axis("off")
        ax.text(
            0.5,
            0.5,
            f"{title}: the loop closure estimated no effect in any campaign",
            ha="center",
            va="center",
            fontsize=9,
        )
        return fig
    first = effects.drop_duplicates("parameter")
    rank = first["block"].map({block: i for i, block in enumerate(EXTENSIONS)}).fillna(len(EXTENSIONS))
    parameters = first.assign(rank=rank).sort_values("rank", kind="stable")["parameter"].tolist()
    units = first.set_index("parameter")["unit"].to_dict()
    return _over_time(effects, title, parameters, "mean", "std", units, lambda name: name)


def transfer_figure(table: pd.DataFrame, title: str) -> plt.Figure:
    """Heat-map of one robot's transfer table for one model: one panel per sensor, rows the
    campaign calibrated on, columns the campaign evaluated on (both in the table's order, date
    order from `transfer.transfer_table`), colour and number the validation RMSE (mm); the
    diagonal is each campaign's own validation.

    `table`: `transfer.transfer_table` rows of one robot and one model (ValueError otherwise).
    """
    if table.empty:
        raise ValueError("no transfer rows to draw")
    _one_robot(table)
    if table["model"].nunique() > 1:
        raise ValueError(f"rows of models {sorted(table['model'].unique())}: draw one model at a time")
    sensors = paper_order(table["sensor"].unique())
    campaigns = list(dict.fromkeys([*table["calibrated_on"], *table["evaluated_on"]]))
    side = max(2.6, 0.55 * len(campaigns) + 1.6)
    fig, axes = _grid(len(sensors), panel_width=side + 0.8, panel_height=side, max_columns=2)
    finite = table["rmse_mm"].to_numpy(dtype=float)
    finite = finite[np.isfinite(finite)]
    top = float(finite.max()) if finite.size else 1.0
    for ax, sensor in zip(axes, sensors):
        rows = table[table["sensor"] == sensor]
        grid = (
            rows.pivot(index="calibrated_on", columns="evaluated_on", values="rmse_mm")
            .reindex(index=campaigns, columns=campaigns)
            .to_numpy(dtype=float)
        )
        image = ax.imshow(grid, cmap="viridis", vmin=0.0, vmax=top if top > 0 else 1.0)
        for (i, j), value in np.ndenumerate(grid):
            if np.isfinite(value):  # dark text on the light end of the scale
                ax.text(
                    j,
                    i,
                    f"{value:.3g}",
                    ha="center",
                    va="center",
                    fontsize=7,
                    color="black" if value > 0.6 * top else "white",
                )
        ax.set_xticks(range(len(campaigns)), campaigns, fontsize=6, rotation=90 if len(campaigns) > 3 else 0)
        ax.set_yticks(range(len(campaigns)), campaigns, fontsize=6)
        ax.set_xlabel("evaluated on", fontsize=8)
        ax.set_ylabel("calibrated on", fontsize=8)
        ax.set_title(sensor_label(sensor), fontsize=9)
        fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04).set_label("validation RMSE (mm)", fontsize=7)
    _suptitle(fig, title, fontsize=10)
    fig.tight_layout()
    return fig


def _suptitle(fig: plt.Figure, title: str, fontsize: float) -> None:
    """The figure's title on one line when it fits the figure's width, else wrapped (textwrap) to it
    (a one-panel figure is narrower than a long robot name)."""
    text = fig.suptitle(title, fontsize=fontsize)
    renderer = fig.canvas.get_renderer()
    room = fig.bbox.width
    columns = len(title)
    while (drawn := text.get_window_extent(renderer).width) > room and columns > 10:
        columns = min(columns - 1, int(0.95 * columns * room / drawn))  # a margin once wrapped
        text.set_text(textwrap.fill(title, columns))


# figure -> (the comparison table it draws, how, title)
OVER_TIME_FIGURES = {
    "zero_offsets_over_time": (
        layout.OVER_TIME_FIGURES["zero_offsets_over_time"],
        zero_offsets_over_time_figure,
        "Zero-offsets over time",
    ),
    "loop_effects_over_time": (
        layout.OVER_TIME_FIGURES["loop_effects_over_time"],
        loop_effects_over_time_figure,
        "Loop-closure effects over time",
    ),
}


def comparison_figures(
    tables: Mapping[str, pd.DataFrame], robots: Mapping[str, str], models: Iterable[str]
) -> Iterator[tuple[str, plt.Figure]]:
    """(file stem, figure) for every cross-campaign figure of every robot (`robots`: file-name slug ->
    robot identity): the OVER_TIME_FIGURES and the transfer heat-map of each model of `models`.
    `tables`: the comparison tables by name, with 'transfer'. Drawn one at a time."""
    for slug, identity in robots.items():
        for figure, (name, draw, title) in OVER_TIME_FIGURES.items():
            table = tables[name]
            yield f"{figure}_{slug}", draw(table[table["robot"] == identity], f"{title}: {identity}")
    transfer = tables["transfer"]
    for model in models:
        for slug, identity in robots.items():
            rows = transfer[(transfer["robot"] == identity) & (transfer["model"] == model)]
            yield f"transfer_{model}_{slug}", transfer_figure(rows, f"Transfer, {model} model: {identity}")
