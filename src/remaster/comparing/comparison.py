"""Across campaigns: one robot's zero-offsets and loop-closure parameters over time, their drift,
and the sensors' agreement.

Functions only (no files). An *entry* is one sensor's posterior summary in one campaign:
`Entry(campaign, date, sensor, summary, robot="", kind=None)`, or a plain tuple of the first four
to six of those. `summary` is the table `posterior_summary.posterior_summary` gives (SI; indexed by parameter
or with a `parameter` column; columns mean, std, status); `robot` is `robot_identity` of the
campaign ('' everywhere = one robot); `kind` is the sensor's kind from campaign.yaml (default:
the sensor's name); `loop` is the loop closure's parameter table (`loop_closure.json` refit
`parameters`: parameter, block, mean_display, std_display, unit, status) or None. Zero-offset
tables report degrees (columns ending _deg); loop-closure tables report each parameter in its
display unit (column `unit`).

Two estimates a and b of one zero-offset, from independent fits, are compared by

    diff = b - a (deg),   combined = sqrt(std_a^2 + std_b^2),   z = diff / combined,

flagged where |z| > significance and both campaigns' loops closed (`loops_closed`). Where one did
not, its model lacks what is left in its residual and its parameters carry that in its own design's
proportions: two designs of one unchanged robot then differ by more than their stds, and the
difference is shown (z) but not flagged as the robot's drift (compare what they predict instead,
`remaster.comparing.predictions`). A parameter held at the controller's value (not identifiable)
in either fit, or absent from one model (an effect the loop closure added in one campaign only),
is reported as not comparable, with no numbers.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple

import numpy as np
import pandas as pd  # scipy.special is imported where it is used: table jobs load this module

from ..calibration.prediction import ZERO_OFFSET_PREFIX
from ..errors import InputError, quoted, require_columns
from ..identity import robot_identity
from ..inference.model import display_value
from ..labels import paper_order
from ..loop.result import LoopReport

ESTIMATED = "estimated"

OVER_TIME_COLUMNS = [
    "campaign",
    "date",
    "robot",
    "sensor",
    "kind",
    "parameter",
    "mean_deg",
    "std_deg",
    "status",
    "loop_closed",
]
_PAIR_COLUMNS = [
    "mean_a_deg",
    "std_a_deg",
    "mean_b_deg",
    "std_b_deg",
    "diff_deg",
    "combined_std_deg",
    "z",
    "loops_closed",
    "flagged",
    "status",
]
DRIFT_COLUMNS = [
    "robot",
    "kind",
    "parameter",
    "campaign_a",
    "date_a",
    "sensor_a",
    "campaign_b",
    "date_b",
    "sensor_b",
] + _PAIR_COLUMNS
AGREEMENT_COLUMNS = ["campaign", "date", "robot", "parameter", "sensor_a", "sensor_b"] + _PAIR_COLUMNS

# The loop closure's registration and noise belong to one campaign's set-up; its marker offset and
# scale to one sensor: compared over time within a sensor kind, never between two sensors.
CAMPAIGN_BLOCKS = ("registration", "noise")
SENSOR_BLOCKS = ("marker_offset", "sensor_scale", "sensor_distortion")
LOOP_OVER_TIME_COLUMNS = [
    "campaign",
    "date",
    "robot",
    "sensor",
    "kind",
    "block",
    "parameter",
    "unit",
    "mean",
    "std",
    "status",
    "effects",
    "loop_closed",
]
NO_EFFECTS = "none"  # the effects of a loop-closure model that added none (the paper's blocks only)
_LOOP_PAIR_COLUMNS = [c.removesuffix("_deg") for c in _PAIR_COLUMNS]
LOOP_DRIFT_COLUMNS = [
    "robot",
    "kind",
    "block",
    "parameter",
    "unit",
    "campaign_a",
    "date_a",
    "sensor_a",
    "campaign_b",
    "date_b",
    "sensor_b",
] + _LOOP_PAIR_COLUMNS
LOOP_AGREEMENT_COLUMNS = [
    "campaign",
    "date",
    "robot",
    "block",
    "parameter",
    "unit",
    "sensor_a",
    "sensor_b",
] + _LOOP_PAIR_COLUMNS


class Entry(NamedTuple):
    """One sensor's posterior summary (SI) in one campaign; see the module docstring. loop_closed: the
    loop closure's verdict (`LoopReport.closed`; None: not known)."""

    campaign: str
    date: str | dt.date
    sensor: str
    summary: pd.DataFrame
    robot: str = ""
    kind: str | None = None
    loop: pd.DataFrame | None = None
    loop_closed: bool | None = None


# --------------------------------------------------------------------------- entries


def _iso_date(value: Any, label: str) -> str:
    if isinstance(value, dt.datetime):
        return value.date().isoformat()
    if isinstance(value, dt.date):
        return value.isoformat()
    try:
        return dt.date.fromisoformat(str(value).strip()).isoformat()
    except ValueError:
        raise InputError(f"must be an ISO date YYYY-MM-DD, got {quoted(value)}", file=label, key="date") from None


def _zero_offsets(entry: Entry, label: str) -> pd.DataFrame:
    """Rows of the summary's zero-offsets, by joint number: mean_deg, std_deg (NaN when held), status."""
    summary = entry.summary
    if not isinstance(summary, pd.DataFrame):
        raise InputError(f"summary must be a DataFrame, got {type(summary).__name__}", file=label)
    if "parameter" in summary.columns:
        summary = summary.set_index("parameter")
    require_columns(summary, ("mean", "std", "status"), file=label, of="a posterior summary")
    names = sorted(
        (str(n) for n in summary.index if str(n).startswith(ZERO_OFFSET_PREFIX)),
        key=lambda n: int(n[len(ZERO_OFFSET_PREFIX) :]),
    )
    if not names:
        raise InputError(f"no {ZERO_OFFSET_PREFIX}N parameters", file=label, key="parameter")
    rows = summary.loc[names]
    held = rows["status"].astype(str) != ESTIMATED
    return pd.DataFrame(
        {
            "parameter": names,
            "mean_deg": [display_value(n, v) for n, v in zip(names, rows["mean"].astype(float))],
            "std_deg": [
                np.nan if h else display_value(n, v) for n, v, h in zip(names, rows["std"].astype(float), held)
            ],
            "status": rows["status"].astype(str).to_numpy(),
        }
    )


def _entries(entries: Iterable) -> list[Entry]:
    """Entries checked: known dates, one entry per (campaign, sensor)."""
    checked, seen = [], set()
    for item in entries:
        entry = item if isinstance(item, Entry) else Entry(*item)
        label = f"{entry.campaign}/{entry.sensor}"
        if (entry.campaign, entry.sensor) in seen:
            raise InputError("given twice", file=label)
        seen.add((entry.campaign, entry.sensor))
        checked.append(
            entry._replace(date=_iso_date(entry.date, label), robot=entry.robot or "", kind=entry.kind or entry.sensor)
        )
    return checked


def zero_offsets_over_time(entries: Iterable) -> pd.DataFrame:
    """Long table of every entry's zero-offsets: one row per (campaign, sensor, parameter).

    Columns OVER_TIME_COLUMNS: campaign, date (ISO text), robot, sensor, kind, parameter
    ('zero_offsets.qJ'), mean_deg, std_deg (NaN when held), status (as in the summary; a held
    parameter's mean_deg is the value it was held at). Sorted by robot, date, campaign, sensor in
    the paper's order, joint.
    """
    return _long_table(entries, _zero_offsets, OVER_TIME_COLUMNS)


def _long_table(entries: Iterable, rows_of, columns: list[str]) -> pd.DataFrame:
    """Every entry's rows_of(entry, label) (None: the entry is left out) with its campaign, date,
    robot, sensor and kind, as `columns`; sorted by robot, date, campaign, sensor in the paper's
    order, then the rows' own order."""
    frames = []
    for entry in _entries(entries):
        rows = rows_of(entry, f"{entry.campaign}/{entry.sensor}")
        if rows is not None:
            frames.append(
                rows.assign(
                    campaign=entry.campaign,
                    date=entry.date,
                    robot=entry.robot,
                    sensor=entry.sensor,
                    kind=entry.kind,
                    loop_closed=entry.loop_closed,
                    position=np.arange(len(rows)),
                )
            )
    if not frames:
        return pd.DataFrame(columns=columns)
    table = pd.concat(frames, ignore_index=True)
    order = {s: i for i, s in enumerate(paper_order(table["sensor"].unique()))}
    table["sensor_order"] = table["sensor"].map(order)
    table = table.sort_values(["robot", "date", "campaign", "sensor_order", "position"], kind="stable")
    return table[columns].reset_index(drop=True)


# --------------------------------------------------------------------------- comparisons


def _compare(
    a: pd.DataFrame, b: pd.DataFrame, label_a: str, label_b: str, significance: float, unit: str = "_deg"
) -> pd.DataFrame:
    """Per parameter of a or b (rows of an over-time table, parameters in a's order then b's): the
    pair columns of b - a, named with `unit` ('_deg': mean_a_deg, ...; '': mean_a, ...). Where the
    rows carry a `unit` column, estimates in different units are not comparable. Where they carry
    an `effects` column (loop-closure models) and the two models' effects differ, no parameter is:
    a zero-offset fitted beside other effects is another quantity (compare such models by what
    they predict, `remaster.calibration.prediction`)."""
    differ = None
    closed = _both_closed(a, b)
    if "effects" in a.columns and "effects" in b.columns and len(a) and len(b):
        effects_a, effects_b = str(a["effects"].iloc[0]), str(b["effects"].iloc[0])
        if effects_a != effects_b:
            differ = f"models differ ({effects_a} vs {effects_b})"
    a, b = a.set_index("parameter"), b.set_index("parameter")
    mean, std = f"mean{unit}", f"std{unit}"
    rows = []
    for name in dict.fromkeys([*a.index, *b.index]):
        row = {"parameter": name}
        why = []
        for side, frame, label in (("a", a, label_a), ("b", b, label_b)):
            present = name in frame.index
            row[f"mean_{side}{unit}"] = frame.at[name, mean] if present else np.nan
            row[f"std_{side}{unit}"] = frame.at[name, std] if present else np.nan
            if not present:
                why.append(f"missing in {label}")
            elif frame.at[name, "status"] != ESTIMATED:  # 'held: x' -> 'held in <label> (x)'
                state, _, detail = str(frame.at[name, "status"]).partition(":")
                why.append(f"{state.strip()} in {label}" + (f" ({detail.strip()})" if detail.strip() else ""))
            elif not np.isfinite(frame.at[name, std]):
                why.append(f"no std in {label}")
        if "unit" in a.columns and name in a.index and name in b.index and a.at[name, "unit"] != b.at[name, "unit"]:
            why.append(f"units differ ({a.at[name, 'unit']}, {b.at[name, 'unit']})")
        combined = float(np.hypot(row[f"std_a{unit}"], row[f"std_b{unit}"]))
        if not why and not combined > 0:
            why.append("zero combined std")
        if differ:
            why = [differ]
        if why:
            row.update(
                {
                    f"diff{unit}": np.nan,
                    f"combined_std{unit}": np.nan,
                    "z": np.nan,
                    "loops_closed": closed,
                    "flagged": False,
                    "status": "not comparable: " + "; ".join(why),
                }
            )
        else:
            diff = row[f"mean_b{unit}"] - row[f"mean_a{unit}"]
            row.update(
                {
                    f"diff{unit}": diff,
                    f"combined_std{unit}": combined,
                    "z": diff / combined,
                    "loops_closed": closed,
                    # beyond the stds, but a loop not closed carries what its model lacks: not the robot's
                    "flagged": bool(abs(diff / combined) > significance) and closed is not False,
                    "status": "compared",
                }
            )
        rows.append(row)
    return pd.DataFrame(rows)


def _both_closed(a: pd.DataFrame, b: pd.DataFrame) -> bool | None:
    """Whether both sides' loops closed (`both_closed`) by their over-time rows."""
    return both_closed(
        *(frame["loop_closed"].iloc[0] if "loop_closed" in frame.columns and len(frame) else None for frame in (a, b))
    )


def both_closed(*verdicts) -> bool | None:
    """Whether every loop closed: False where one did not, None where one is not known (None, NaN)."""
    verdicts = [None if v is None or (isinstance(v, float) and np.isnan(v)) else bool(v) for v in verdicts]
    if False in verdicts:
        return False
    return None if None in verdicts else True


def _described(pairs: pd.DataFrame, rows: pd.DataFrame) -> pd.DataFrame:
    """Loop-closure pairs with each parameter's block and unit (from the over-time rows)."""
    known = rows.drop_duplicates("parameter").set_index("parameter")
    return pairs.assign(block=pairs["parameter"].map(known["block"]), unit=pairs["parameter"].map(known["unit"]))


def consecutive_pairs(table: pd.DataFrame):
    """(robot, kind, rows of a, rows of b) for consecutive campaigns a, b within each (robot,
    kind) of an over-time table (campaigns ordered by date, then name), every sensor of that kind
    in a with every one in b."""
    for (robot, kind), group in table.groupby(["robot", "kind"], sort=True):
        campaigns = group[["date", "campaign"]].drop_duplicates().sort_values(["date", "campaign"])
        names = campaigns["campaign"].tolist()
        for first, second in zip(names, names[1:]):
            for _, a in group[group["campaign"] == first].groupby("sensor", sort=False):
                for _, b in group[group["campaign"] == second].groupby("sensor", sort=False):
                    yield robot, kind, a, b


def sensor_pairs(table: pd.DataFrame):
    """(rows of sensor a, rows of sensor b) for each pair of sensors within each campaign of an
    over-time table, sensors in the paper's order (a the earlier)."""
    for _, group in table.groupby("campaign", sort=False):
        sensors = paper_order(group["sensor"].unique())
        for i, sensor_a in enumerate(sensors):
            for sensor_b in sensors[i + 1 :]:
                yield group[group["sensor"] == sensor_a], group[group["sensor"] == sensor_b]


def _drift_pairs(table: pd.DataFrame, significance: float, unit: str) -> list[pd.DataFrame]:
    """`_compare` of consecutive campaigns within each (robot, kind) of an over-time table."""
    pairs = []
    for robot, kind, a, b in consecutive_pairs(table):
        first, second = a["campaign"].iloc[0], b["campaign"].iloc[0]
        pair = _compare(a, b, first, second, significance, unit)
        if "block" in table.columns:
            pair = _described(pair, pd.concat([a, b]))
        pairs.append(
            pair.assign(
                robot=robot,
                kind=kind,
                campaign_a=first,
                date_a=a["date"].iloc[0],
                sensor_a=a["sensor"].iloc[0],
                campaign_b=second,
                date_b=b["date"].iloc[0],
                sensor_b=b["sensor"].iloc[0],
            )
        )
    return pairs


def _agreement_pairs(table: pd.DataFrame, significance: float, unit: str) -> list[pd.DataFrame]:
    """`_compare` of each pair of sensors within each campaign of an over-time table."""
    pairs = []
    for a, b in sensor_pairs(table):
        sensor_a, sensor_b = a["sensor"].iloc[0], b["sensor"].iloc[0]
        pair = _compare(a, b, sensor_a, sensor_b, significance, unit)
        if "block" in table.columns:
            pair = _described(pair, pd.concat([a, b]))
        pairs.append(
            pair.assign(
                campaign=a["campaign"].iloc[0],
                date=a["date"].iloc[0],
                robot=a["robot"].iloc[0],
                sensor_a=sensor_a,
                sensor_b=sensor_b,
            )
        )
    return pairs


def _joined(pairs: list[pd.DataFrame], columns: list[str]) -> pd.DataFrame:
    return pd.concat(pairs, ignore_index=True)[columns] if pairs else pd.DataFrame(columns=columns)


def drift_between(entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """Zero-offset drift between consecutive campaigns of the same robot and sensor kind.

    Within each (robot, kind), campaigns are ordered by date (then name); every sensor of that kind
    in a campaign is compared with every one in the next campaign (one pair when each campaign
    has one sensor per kind). Columns DRIFT_COLUMNS: a is the earlier campaign, diff_deg = b - a,
    combined_std_deg, z, flagged (|z| > significance), status ('compared' or 'not comparable: ...').
    """
    return _joined(_drift_pairs(zero_offsets_over_time(entries), significance, "_deg"), DRIFT_COLUMNS)


def sensor_agreement(entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """Per campaign and zero-offset, each pair of its sensors compared (none for a single sensor).

    Sensors in the paper's order (motion capture, laser tracker, then others by name): a is the
    earlier, diff_deg = b - a. Columns AGREEMENT_COLUMNS, as in `drift_between`.
    """
    return _joined(_agreement_pairs(zero_offsets_over_time(entries), significance, "_deg"), AGREEMENT_COLUMNS)


# --------------------------------------------------------------------------- loop closure


def _loop_rows(entry: Entry, label: str) -> pd.DataFrame | None:
    """The entry's loop-closure parameters outside CAMPAIGN_BLOCKS, in display units: block,
    parameter, unit, mean, std (NaN unless estimated), status; None without a loop closure."""
    loop = entry.loop
    if loop is None:
        return None
    if not isinstance(loop, pd.DataFrame):
        raise InputError(f"loop-closure parameters must be a DataFrame, got {type(loop).__name__}", file=label)
    columns = ("parameter", "block", "mean_display", "std_display", "unit", "status")
    require_columns(loop, columns, file=label, of="the loop closure's parameter table")
    rows = loop[~loop["block"].isin(CAMPAIGN_BLOCKS)]
    estimated = rows["status"].astype(str) == ESTIMATED
    return pd.DataFrame(
        {
            "block": rows["block"].astype(str),
            "parameter": rows["parameter"].astype(str),
            "unit": rows["unit"].astype(str),
            "mean": rows["mean_display"].astype(float),
            "std": rows["std_display"].astype(float).where(estimated),
            "status": rows["status"].astype(str),
            "effects": loop_effects(loop),
        }
    ).reset_index(drop=True)


def loop_effects(loop: pd.DataFrame) -> str:
    """The effects of a loop-closure model from its whole parameter table (every block's
    parameters are listed, held ones too), in model order: 'link_geometry + joint_compliance',
    NO_EFFECTS for the paper's blocks only."""
    base = {"zero_offsets", *CAMPAIGN_BLOCKS}
    effects = [b for b in dict.fromkeys(loop["block"].astype(str)) if b not in base]
    return " + ".join(effects) or NO_EFFECTS


def loop_parameters_over_time(entries: Iterable) -> pd.DataFrame:
    """Long table of every entry's loop-closure model: the zero-offsets refitted with the effects
    the loop closure added, and those effects' parameters; one row per (campaign, sensor,
    parameter). Entries without `loop` are left out.

    Columns LOOP_OVER_TIME_COLUMNS (mean, std in the parameter's display `unit`; std NaN unless
    estimated). Sorted by robot, date, campaign, sensor in the paper's order, model order.
    """
    return _long_table(entries, _loop_rows, LOOP_OVER_TIME_COLUMNS)


def loop_parameter_drift(entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """`drift_between` for the loop-closure parameters (LOOP_DRIFT_COLUMNS, display units), between
    models of the same effects only: where the two campaigns' loop closures added different effects,
    every row is 'not comparable: models differ (<effects a> vs <effects b>)', without z."""
    return _joined(_drift_pairs(loop_parameters_over_time(entries), significance, ""), LOOP_DRIFT_COLUMNS)


def loop_parameter_agreement(entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """`sensor_agreement` for the loop-closure parameters (LOOP_AGREEMENT_COLUMNS, display units),
    SENSOR_BLOCKS left out: each sensor has its own marker and scale. Models of different effects
    (those blocks included) are not comparable, as in `loop_parameter_drift`."""
    table = loop_parameters_over_time(entries)
    table = table[~table["block"].isin(SENSOR_BLOCKS)]
    return _joined(_agreement_pairs(table, significance, ""), LOOP_AGREEMENT_COLUMNS)


def entries_of(
    metadata: Mapping[str, Mapping],
    summaries: Mapping[tuple[str, str], pd.DataFrame],
    loops: Mapping[tuple[str, str], LoopReport] | None = None,
) -> list[Entry]:
    """Comparison entries from each campaign's campaign.yaml content (campaign -> mapping), each
    sensor's posterior summary ((campaign, sensor) -> `posterior_summary.posterior_summary` table) and, when
    given, its loop closure's report ((campaign, sensor) -> `LoopReport.read`)."""
    loops = loops or {}
    return [
        Entry(
            campaign,
            metadata[campaign]["date"],
            sensor,
            summary,
            robot_identity(metadata[campaign]),
            metadata[campaign]["sensors"][sensor]["kind"],
            loops[(campaign, sensor)].parameters if (campaign, sensor) in loops else None,
            loops[(campaign, sensor)].closed if (campaign, sensor) in loops else None,
        )
        for (campaign, sensor), summary in summaries.items()
    ]


def drift_calibration(drift: pd.DataFrame, significance: float = 3.0) -> pd.DataFrame:
    """How honest the drift flags are, on campaigns known to share one truth (repeat campaigns of
    one robot, such as a simulated fleet): there every z should be standard normal.

    `drift`: a `drift_between` or `loop_parameter_drift` table. Per parameter, over its compared
    pairs: pairs, z_mean, z_std (1 when the stds are honest; above 1, drift is flagged that is
    not there), flagged, and expected_flagged = pairs * P(|N(0, 1)| > significance).
    """
    compared = drift[drift["status"] == "compared"]
    table = compared.groupby("parameter", sort=False).agg(
        pairs=("z", "size"), z_mean=("z", "mean"), z_std=("z", "std"), flagged=("flagged", "sum")
    )
    import scipy.special

    table["expected_flagged"] = table["pairs"] * 2.0 * scipy.special.ndtr(-significance)
    return table.reset_index()


TABLES = {
    "zero_offsets_over_time": lambda entries, significance: zero_offsets_over_time(entries),
    "drift_between_campaigns": drift_between,
    "sensor_agreement": sensor_agreement,
    "loop_parameters_over_time": lambda entries, significance: loop_parameters_over_time(entries),
    "loop_parameter_drift": loop_parameter_drift,
    "loop_parameter_agreement": loop_parameter_agreement,
}
LOOP_TABLES = ("loop_parameters_over_time", "loop_parameter_drift", "loop_parameter_agreement")


def table(name: str, entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """One of the cross-campaign tables by name (see TABLES)."""
    if name not in TABLES:
        raise ValueError(f"unknown comparison table {name!r}; tables: {sorted(TABLES)}")
    return TABLES[name](entries, significance)


def comparison_tables(
    metadata: Mapping[str, Mapping],
    summaries: Mapping[tuple[str, str], pd.DataFrame],
    loops: Mapping[tuple[str, str], LoopReport],
    significance: float = 3.0,
) -> dict[str, pd.DataFrame]:
    """Every table of TABLES, from the arguments of `entries_of`."""
    return tables_of(entries_of(metadata, summaries, loops), significance)


def tables_of(entries: Iterable, significance: float = 3.0) -> dict[str, pd.DataFrame]:
    """Every table of TABLES, of these entries."""
    return {name: table(name, entries, significance) for name in TABLES}
