"""Across campaigns: one robot's zero-offsets over time, their drift, and the sensors' agreement.

Functions only (no files). An *entry* is one sensor's posterior summary in one campaign:
`Entry(campaign, date, sensor, summary, robot="", kind=None)`, or a plain tuple of the first four
to six of those. `summary` is the table `fit.posterior_summary` gives (SI; indexed by parameter
or with a `parameter` column; columns mean, std, status); `robot` is `robot_identity` of the
campaign ('' everywhere = one robot); `kind` is the sensor's kind from campaign.yaml (default:
the sensor's name). Tables report degrees (columns ending _deg).

Two estimates a and b of one zero-offset, from independent fits, are compared by

    diff = b - a (deg),   combined = sqrt(std_a^2 + std_b^2),   z = diff / combined,

flagged where |z| > significance. A parameter held at the controller's value (not identifiable)
in either fit is reported as not comparable, with no numbers.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
from collections.abc import Iterable, Mapping
from pathlib import PurePosixPath
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from .errors import InputError
from .tables import display_value, paper_order

ZERO_OFFSET_PREFIX = "zero_offsets.q"
ESTIMATED = "estimated"
DH_DIGITS = 9  # DH values are rounded to 1e-9 (m, rad) before they are hashed

OVER_TIME_COLUMNS = ["campaign", "date", "robot", "sensor", "kind", "parameter", "mean_deg", "std_deg", "status"]
_PAIR_COLUMNS = ["mean_a_deg", "std_a_deg", "mean_b_deg", "std_b_deg", "diff_deg", "combined_std_deg", "z",
                 "flagged", "status"]
DRIFT_COLUMNS = ["robot", "kind", "parameter", "campaign_a", "date_a", "sensor_a", "campaign_b", "date_b",
                 "sensor_b"] + _PAIR_COLUMNS
AGREEMENT_COLUMNS = ["campaign", "date", "robot", "parameter", "sensor_a", "sensor_b"] + _PAIR_COLUMNS


class Entry(NamedTuple):
    """One sensor's posterior summary (SI) in one campaign; see the module docstring."""

    campaign: str
    date: str | dt.date
    sensor: str
    summary: pd.DataFrame
    robot: str = ""
    kind: str | None = None


# --------------------------------------------------------------------------- robot identity


def _robot_section(campaign: Any) -> Mapping[str, Any]:
    robot = getattr(campaign, "robot", None)  # a remaster.campaign.Campaign
    if robot is None and isinstance(campaign, Mapping):
        robot = campaign.get("robot", campaign)  # campaign.yaml / summary.json content, or the section itself
    if not isinstance(robot, Mapping):
        raise InputError(f"no robot section in {type(campaign).__name__}", key="robot")
    return robot


def _rounded(values) -> list:
    """Nested numbers rounded to DH_DIGITS, -0.0 as 0.0."""
    if isinstance(values, (list, tuple, np.ndarray)):
        return [_rounded(v) for v in values]
    return round(float(values), DH_DIGITS) + 0.0


def robot_identity(campaign: Any) -> str:
    """A key equal for campaigns of the same robot model (the same kinematic chain).

    `campaign`: a `Campaign`, campaign.yaml's content, its `robot` section, or the summary.json
    `campaign.summarize` writes. The key:
    - URDF: 'urdf:<file name>:<base>:<flange>' (directory dropped: kuka-twin and kuka-twin-2019
      both give 'urdf:kuka_iiwa14.urdf:iiwa_link_0:iiwa_link_ee'; base/flange empty when not given);
      used also when a DH table is given beside the URDF, as the reader checks they agree;
    - DH only: 'dh:<convention>:<12 hex>', a SHA-256 of the rows and flange rounded to 1e-9;
    - a campaign summary (no urdf/dh, the chain's name, joints and frames):
      'chain:<name>:<base>:<flange>:<n> joints'. This form never equals the others, and a DH chain
      is named after its campaign there: compare campaigns from the same kind of input,
      preferably campaign.yaml.
    Two campaign-local URDFs of the same file name are taken for the same model; the key names the
    model, not the physical unit, unless the robot section gives the unit's `serial`: then the key
    is 'serial:<serial>', and only campaigns of that very robot are compared.
    """
    robot = _robot_section(campaign)
    if robot.get("serial"):
        return f"serial:{robot['serial']}"
    if robot.get("urdf"):
        name = PurePosixPath(str(robot["urdf"]).replace("\\", "/")).name
        return f"urdf:{name}:{robot.get('base') or ''}:{robot.get('flange') or ''}"
    if robot.get("dh"):
        dh = robot["dh"]
        content = {"convention": dh.get("convention", "standard"), "rows": _rounded(dh["rows"]),
                   "flange": None if dh.get("flange") is None else _rounded(dh["flange"])}
        digest = hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:12]
        return f"dh:{content['convention']}:{digest}"
    if robot.get("joints"):
        return f"chain:{robot.get('name', '')}:{robot.get('base') or ''}:{robot.get('flange') or ''}:" \
               f"{len(robot['joints'])} joints"
    raise InputError("names no robot model (urdf or dh, or a summary's chain)", key="robot")


# --------------------------------------------------------------------------- entries


def _iso_date(value: Any, label: str) -> str:
    if isinstance(value, dt.datetime):
        return value.date().isoformat()
    if isinstance(value, dt.date):
        return value.isoformat()
    try:
        return dt.date.fromisoformat(str(value).strip()).isoformat()
    except ValueError:
        raise InputError(f"must be an ISO date YYYY-MM-DD, got {value!r}", file=label, key="date") from None


def _zero_offsets(entry: Entry, label: str) -> pd.DataFrame:
    """Rows of the summary's zero-offsets, by joint number: mean_deg, std_deg (NaN when held), status."""
    summary = entry.summary
    if not isinstance(summary, pd.DataFrame):
        raise InputError(f"summary must be a DataFrame, got {type(summary).__name__}", file=label)
    if "parameter" in summary.columns:
        summary = summary.set_index("parameter")
    missing = [c for c in ("mean", "std", "status") if c not in summary.columns]
    if missing:
        raise InputError("missing column(s) of a posterior summary", file=label, key=", ".join(missing))
    names = sorted((str(n) for n in summary.index if str(n).startswith(ZERO_OFFSET_PREFIX)),
                   key=lambda n: int(n[len(ZERO_OFFSET_PREFIX):]))
    if not names:
        raise InputError(f"no {ZERO_OFFSET_PREFIX}N parameters", file=label, key="parameter")
    rows = summary.loc[names]
    held = rows["status"].astype(str) != ESTIMATED
    return pd.DataFrame({
        "parameter": names,
        "mean_deg": [display_value(n, v) for n, v in zip(names, rows["mean"].astype(float))],
        "std_deg": [np.nan if h else display_value(n, v) for n, v, h in zip(names, rows["std"].astype(float), held)],
        "status": rows["status"].astype(str).to_numpy(),
    })


def _entries(entries: Iterable) -> list[Entry]:
    """Entries checked: known dates, one entry per (campaign, sensor)."""
    checked, seen = [], set()
    for item in entries:
        entry = item if isinstance(item, Entry) else Entry(*item)
        label = f"{entry.campaign}/{entry.sensor}"
        if (entry.campaign, entry.sensor) in seen:
            raise InputError("given twice", file=label)
        seen.add((entry.campaign, entry.sensor))
        checked.append(entry._replace(date=_iso_date(entry.date, label), robot=entry.robot or "",
                                      kind=entry.kind or entry.sensor))
    return checked


def zero_offsets_over_time(entries: Iterable) -> pd.DataFrame:
    """Long table of every entry's zero-offsets: one row per (campaign, sensor, parameter).

    Columns OVER_TIME_COLUMNS: campaign, date (ISO text), robot, sensor, kind, parameter
    ('zero_offsets.qJ'), mean_deg, std_deg (NaN when held), status (as in the summary; a held
    parameter's mean_deg is the value it was held at). Sorted by robot, date, campaign, sensor in
    the paper's order, joint.
    """
    frames = []
    for entry in _entries(entries):
        rows = _zero_offsets(entry, f"{entry.campaign}/{entry.sensor}")
        frames.append(rows.assign(campaign=entry.campaign, date=entry.date, robot=entry.robot, sensor=entry.sensor,
                                  kind=entry.kind, joint=np.arange(len(rows))))
    if not frames:
        return pd.DataFrame(columns=OVER_TIME_COLUMNS)
    table = pd.concat(frames, ignore_index=True)
    order = {s: i for i, s in enumerate(paper_order(table["sensor"].unique()))}
    table["sensor_order"] = table["sensor"].map(order)
    table = table.sort_values(["robot", "date", "campaign", "sensor_order", "joint"], kind="stable")
    return table[OVER_TIME_COLUMNS].reset_index(drop=True)


# --------------------------------------------------------------------------- comparisons


def _compare(a: pd.DataFrame, b: pd.DataFrame, label_a: str, label_b: str, significance: float) -> pd.DataFrame:
    """Per parameter of a or b (rows of `zero_offsets_over_time`): the _PAIR_COLUMNS of b - a."""
    a, b = a.set_index("parameter"), b.set_index("parameter")
    names = sorted(set(a.index) | set(b.index), key=lambda n: int(n[len(ZERO_OFFSET_PREFIX):]))
    rows = []
    for name in names:
        row = {"parameter": name}
        why = []
        for side, frame, label in (("a", a, label_a), ("b", b, label_b)):
            present = name in frame.index
            row[f"mean_{side}_deg"] = frame.at[name, "mean_deg"] if present else np.nan
            row[f"std_{side}_deg"] = frame.at[name, "std_deg"] if present else np.nan
            if not present:
                why.append(f"missing in {label}")
            elif frame.at[name, "status"] != ESTIMATED:  # 'held: x' -> 'held in <label> (x)'
                state, _, detail = str(frame.at[name, "status"]).partition(":")
                why.append(f"{state.strip()} in {label}" + (f" ({detail.strip()})" if detail.strip() else ""))
            elif not np.isfinite(frame.at[name, "std_deg"]):
                why.append(f"no std in {label}")
        combined = float(np.hypot(row["std_a_deg"], row["std_b_deg"]))
        if not why and not combined > 0:
            why.append("zero combined std")
        if why:
            row.update(diff_deg=np.nan, combined_std_deg=np.nan, z=np.nan, flagged=False,
                       status="not comparable: " + "; ".join(why))
        else:
            diff = row["mean_b_deg"] - row["mean_a_deg"]
            row.update(diff_deg=diff, combined_std_deg=combined, z=diff / combined,
                       flagged=bool(abs(diff / combined) > significance), status="compared")
        rows.append(row)
    return pd.DataFrame(rows)


def drift_between(entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """Zero-offset drift between consecutive campaigns of the same robot and sensor kind.

    Within each (robot, kind), campaigns are ordered by date (then name); every sensor of that kind
    in a campaign is compared with every one in the next campaign (one pair when each campaign
    has one sensor per kind). Columns DRIFT_COLUMNS: a is the earlier campaign, diff_deg = b - a,
    combined_std_deg, z, flagged (|z| > significance), status ('compared' or 'not comparable: ...').
    """
    table = zero_offsets_over_time(entries)
    pairs = []
    for (robot, kind), group in table.groupby(["robot", "kind"], sort=True):
        campaigns = group[["date", "campaign"]].drop_duplicates().sort_values(["date", "campaign"])
        names = campaigns["campaign"].tolist()
        for first, second in zip(names, names[1:]):
            for sensor_a, a in group[group["campaign"] == first].groupby("sensor", sort=False):
                for sensor_b, b in group[group["campaign"] == second].groupby("sensor", sort=False):
                    pair = _compare(a, b, first, second, significance)
                    pairs.append(pair.assign(robot=robot, kind=kind, campaign_a=first, date_a=a["date"].iloc[0],
                                             sensor_a=sensor_a, campaign_b=second, date_b=b["date"].iloc[0],
                                             sensor_b=sensor_b))
    if not pairs:
        return pd.DataFrame(columns=DRIFT_COLUMNS)
    return pd.concat(pairs, ignore_index=True)[DRIFT_COLUMNS]


def sensor_agreement(entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """Per campaign and zero-offset, each pair of its sensors compared (none for a single sensor).

    Sensors in the paper's order (motion capture, laser tracker, then others by name): a is the
    earlier, diff_deg = b - a. Columns AGREEMENT_COLUMNS, as in `drift_between`.
    """
    table = zero_offsets_over_time(entries)
    pairs = []
    for campaign, group in table.groupby("campaign", sort=False):
        sensors = paper_order(group["sensor"].unique())
        for i, sensor_a in enumerate(sensors):
            for sensor_b in sensors[i + 1:]:
                a, b = group[group["sensor"] == sensor_a], group[group["sensor"] == sensor_b]
                pair = _compare(a, b, sensor_a, sensor_b, significance)
                pairs.append(pair.assign(campaign=campaign, date=a["date"].iloc[0], robot=a["robot"].iloc[0],
                                         sensor_a=sensor_a, sensor_b=sensor_b))
    if not pairs:
        return pd.DataFrame(columns=AGREEMENT_COLUMNS)
    return pd.concat(pairs, ignore_index=True)[AGREEMENT_COLUMNS]


def entries_of(metadata: Mapping[str, Mapping], summaries: Mapping[tuple[str, str], pd.DataFrame]) -> list[Entry]:
    """Comparison entries from each campaign's campaign.yaml content (campaign -> mapping) and
    each sensor's posterior summary ((campaign, sensor) -> `fit.posterior_summary` table)."""
    return [Entry(campaign, metadata[campaign]["date"], sensor, summary, robot_identity(metadata[campaign]),
                  metadata[campaign]["sensors"][sensor]["kind"])
            for (campaign, sensor), summary in summaries.items()]


TABLES = {"zero_offsets_over_time": lambda entries, significance: zero_offsets_over_time(entries),
          "drift_between_campaigns": drift_between, "sensor_agreement": sensor_agreement}


def table(name: str, entries: Iterable, significance: float = 3.0) -> pd.DataFrame:
    """One of the cross-campaign tables by name (see TABLES)."""
    if name not in TABLES:
        raise ValueError(f"unknown comparison table {name!r}; tables: {sorted(TABLES)}")
    return TABLES[name](entries, significance)


def robot_slug(identity: str) -> str:
    """A file-name-safe short form of a robot identity."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in identity)[:80]
