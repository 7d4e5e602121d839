"""The HTML report: one self-contained page with every table and figure, the page a person reads
first. Tables come in as DataFrames and figures as PNG bytes (embedded as data URIs), so the
page needs nothing beside it."""

from __future__ import annotations

import base64
import html
import urllib.parse
from dataclasses import dataclass, field

import pandas as pd

from .. import __version__
from .tables import formatted

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1500px; padding: 0 1em; color: #222; }
h1 { border-bottom: 2px solid #444; } h2 { margin-top: 2em; border-bottom: 1px solid #aaa; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.85em; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: right; }
th { background: #eee; } td:first-child, th:first-child { text-align: left; }
figure { margin: 1em 0 2em; } figure img { max-width: 100%; } figcaption, caption { font-weight: bold; text-align: left; }
.note { color: #555; } nav a { margin-right: 1em; } .warning { color: #8a3b00; }
details { margin: 0.3em 0; } summary { cursor: pointer; color: #234; }
tr.failed td { background: #fde8e8; color: #a00000; white-space: pre-wrap; text-align: left; }
"""


PREDICTION_NOTES = (
    "Transfer: each campaign's calibration (rows, calibrated on) applied to each campaign of the same robot "
    "and sensor (columns, evaluated on), the registration refitted there with the calibration's kinematics "
    "frozen. The diagonal is each campaign's own validation; off the diagonal is what the calibration is worth "
    "on another campaign of the robot: close to the diagonal, the robot has not changed; larger, it has (or "
    "the calibration fitted that campaign's set-up). The nominal rows are the robot as the controller knows it.",
    "Drift and agreement by prediction: the change of predicted marker position (robot frame) at configurations "
    "inside both calibrations' measured domains, at the posterior means (mean_mm, p95_mm). It is flagged when "
    "what is left of it after the rigid motion that best aligns the two (aligned_mean_mm: a re-registration "
    "absorbs the rest) exceeds null_p95_of_aligned_mean_mm, the 95th percentile of the same under posterior "
    "uncertainty alone, and both loops closed: unlike the parameter tables, it stays meaningful between models of different effects.",
)


@dataclass
class Section:
    """A part of the report: a title, notes (plain text paragraphs), tables and figures."""

    title: str
    notes: list[str] = field(default_factory=list)
    tables: list[tuple[str, pd.DataFrame]] = field(default_factory=list)
    figures: list[tuple[str, bytes]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    lead_tables: list[tuple[str, pd.DataFrame]] = field(default_factory=list)  # shown first, open
    lead_figures: list[tuple[str, bytes]] = field(default_factory=list)
    fold: bool = False  # the (long) tables and figures after the lead fold away, each under its caption
    failed: dict[str, str] = field(default_factory=dict)  # campaign -> what failed: red rows, shown first

    @property
    def anchor(self) -> str:
        return "".join(c if c.isalnum() else "-" for c in self.title.lower())


LINK_COLUMN = "File"  # a column of paths from the results folder (where the page is): shown as links


def relative_href(path: str) -> str:
    """A path from the page's folder as an href that can only be one: percent-encoded, so that a
    campaign folder named `javascript:alert(1)` or `https:` gives no scheme, and after "./", so
    that `//host` names no other host."""
    return "./" + urllib.parse.quote(path, safe="/")


def _td(column: str, cell: str) -> str:
    text = html.escape(cell)
    return f'<td><a href="{relative_href(cell)}">{text}</a></td>' if column == LINK_COLUMN else f"<td>{text}</td>"


def table_html(caption: str, table: pd.DataFrame) -> str:
    """An HTML table, numbers rounded to their uncertainty (`tables.formatted`)."""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in table.columns)
    rows = "".join(
        "<tr>" + "".join(_td(str(c), cell) for c, cell in zip(table.columns, cells)) + "</tr>"
        for cells in formatted(table)
    )
    return (
        f"<table><caption>{html.escape(caption)}</caption><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>"
    )


FAILED_CAPTION = "Campaigns that failed in this run (none of their numbers is in this report)"


def failed_html(failed: dict[str, str]) -> str:
    """The failed campaigns as a table of red rows: the campaign and what failed (its job's log and
    the exception it ends with)."""
    rows = "".join(
        f"<tr class='failed'><td>{html.escape(name)}</td><td>{html.escape(message)}</td></tr>"
        for name, message in failed.items()
    )
    return (
        f"<table><caption>{html.escape(FAILED_CAPTION)}</caption><thead><tr><th>Campaign</th><th>What failed</th>"
        f"</tr></thead><tbody>{rows}</tbody></table>"
    )


def figure_html(caption: str, png: bytes) -> str:
    data = base64.b64encode(png).decode("ascii")
    return (
        f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
    )


def render(title: str, intro: list[str], sections: list[Section]) -> str:
    """The whole page as HTML text (UTF-8, no external resources)."""
    parts = [
        f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
        f"<style>{STYLE}</style></head><body><h1>{html.escape(title)}</h1>",
    ]
    parts += [f"<p class='note'>{html.escape(p)}</p>" for p in intro]
    parts.append("<nav>" + "".join(f"<a href='#{s.anchor}'>{html.escape(s.title)}</a>" for s in sections) + "</nav>")
    for section in sections:
        parts.append(f"<h2 id='{section.anchor}'>{html.escape(section.title)}</h2>")
        parts += [f"<p class='note'>{html.escape(n)}</p>" for n in section.notes]
        if section.warnings:
            parts.append(
                "<ul>" + "".join(f"<li class='warning'>{html.escape(w)}</li>" for w in section.warnings) + "</ul>"
            )
        if section.failed:
            parts.append(failed_html(section.failed))
        parts += [table_html(c, t) for c, t in section.lead_tables]
        parts += [figure_html(c, f) for c, f in section.lead_figures]
        rest = [(c, table_html(c, t)) for c, t in section.tables] + [(c, figure_html(c, f)) for c, f in section.figures]
        parts += [
            f"<details><summary>{html.escape(c)}</summary>{item}</details>" if section.fold else item
            for c, item in rest
        ]
    parts.append(f"<p class='note'>Generated by remaster {html.escape(__version__)}.</p></body></html>")
    return "\n".join(parts) + "\n"


def _summary_notes(summary: dict) -> list[str]:
    notes = [
        f"{summary['campaign']}, measured {summary['date']}: robot {summary['robot']['name']} "
        f"({len(summary['robot']['joints'])} joints, base {summary['robot']['base']}, "
        f"flange {summary['robot']['flange']})."
    ]
    for sensor, info in summary["sensors"].items():
        sets = ", ".join(
            f"{name} {s['poses']} poses / {s['configurations']} configurations" for name, s in info["sets"].items()
        )
        missing = (
            f"; {info['n_missing']} rows without a measurement (kept, excluded from fits): {info['missing_rows']}"
            if info["n_missing"]
            else ""
        )
        notes.append(f"{sensor} ({info['kind']}): {sets}{missing}.")
    return notes


def audit_section(audit: dict) -> Section:
    """Where every result came from: per campaign its content hash, with the run's configuration
    hash, package version and seed (the full record is results/audit.json)."""
    table = pd.DataFrame(
        [
            {
                "campaign": name,
                "content SHA-256": record["content_sha256"],
                "files": len(record["files"]),
                "results": len(record["results"]),
            }
            for name, record in audit["campaigns"].items()
        ]
    )
    notes = [
        f"remaster {audit['remaster_version']} (Python {audit['python']}), seed {audit['seed']}, "
        f"configuration SHA-256 {audit['config_sha256']}. Every result file's SHA-256 is in results/audit.json."
    ]
    return Section("Audit trail", notes, [("Campaign content hashes", table)])


CERTIFICATE_TABLES = ("certificate_", "uncertainty_budget")  # a campaign's certificate, shown open
CERTIFICATE_FIGURES = ("post_registration_histograms", "loop_residuals")  # errors before/after, shown open


def overview(campaigns: dict[str, dict]) -> pd.DataFrame:
    """The run at a glance: every campaign's certificate verdicts (`certificate_verdict` tables);
    without them, per campaign and sensor, the mean post-registration error before (Vernier) and
    after (Bayesian) zero-offset remastering, and what the loop closure added and left on the
    validation set. Built from the campaigns' own tables."""
    from ..labels import sensor_label

    verdicts = [
        content["tables"]["certificate_verdict"]
        for content in campaigns.values()
        if "certificate_verdict" in content["tables"]
    ]
    if verdicts:
        return pd.concat(verdicts, ignore_index=True)
    rows = []
    for name, content in campaigns.items():
        accuracy = content["tables"].get("post_registration_accuracy")
        loop = content["tables"].get("loop_closure")
        if accuracy is None:
            continue
        for sensor in accuracy["Reference Sensor"].unique():
            mean = {
                m: accuracy.loc[
                    (accuracy["Remastering Method"] == m) & (accuracy["Reference Sensor"] == sensor), "Mean (mm)"
                ].iloc[0]
                for m in ("Vernier", "Bayesian")
            }
            row = {
                "Campaign": name,
                "Sensor": sensor,
                "Vernier error (mm)": mean["Vernier"],
                "Bayesian error (mm)": mean["Bayesian"],
            }
            if loop is not None:
                mine = loop[loop["Sensor"].map(sensor_label) == sensor]
                rmse = mine[mine["Quantity"] == "validation: post-registration RMSE (mm)"]
                row["Loop closure added"] = mine["Effects added"].iloc[0] if len(mine) else ""
                row["Validation RMSE before (mm)"] = rmse["Before (zero-offsets)"].iloc[0] if len(rmse) else None
                row["Validation RMSE after (mm)"] = rmse["After (with effects)"].iloc[0] if len(rmse) else None
            rows.append(row)
    return pd.DataFrame(rows)


def _campaign_section(name: str, content: dict, caption) -> Section:
    """A campaign's section: its certificate (heading, warnings, tables, the before/after figures)
    open, then every other table and figure folded under its caption."""
    cert = content.get("certificate") or {}
    lead = [t for t in content["tables"] if t.startswith(CERTIFICATE_TABLES)]
    lead_figures = [f for f in content["figures"] if f.startswith(CERTIFICATE_FIGURES)] if cert else []
    return Section(
        name,
        [*cert.get("brief", []), *cert.get("heading", []), *_summary_notes(content["summary"])],
        [(caption(t), table) for t, table in content["tables"].items() if t not in lead],
        [(caption(f), png) for f, png in content["figures"].items() if f not in lead_figures],
        warnings=list(cert.get("warnings", [])),
        lead_tables=[(caption(t), content["tables"][t]) for t in lead],
        lead_figures=[(caption(f), content["figures"][f]) for f in lead_figures],
        fold=bool(cert),
    )


def _overview_section(glance: pd.DataFrame, failed: dict[str, str]) -> list[Section]:
    """The overview (none when there is nothing to show): the failed campaigns' red rows, then every
    campaign's verdict."""
    if not len(glance) and not failed:
        return []
    notes = [
        "Every campaign's verdict (its certificate, below): the error before and "
        "after on the validation set, what the calibration claims inside the measured "
        "joint ranges and across the joint limits, whether the loop is closed and where "
        "the calibration holds."
    ]
    return [Section("Overview", notes, [("The run at a glance", glance)] if len(glance) else [], failed=failed)]


def _intro(failed: dict[str, str], reported: int) -> list[str]:
    intro = [
        "Bayesian remastering of robot joint zero-offsets from external 3D measurements, after Van Wyk, "
        "Falco and Cheok (NIST). Lengths in mm, angles in deg. Parameters the data cannot determine are "
        "marked 'held' (kept at the controller's value)."
    ]
    if failed:
        intro.append(
            f"This run failed for {len(failed)} of its {len(failed) + reported} campaigns "
            f"({', '.join(failed)}): they are the red rows of the overview, with what failed; this report, its "
            "comparisons across campaigns and its audit trail are of the other campaigns alone."
        )
    return intro


def build(
    campaigns: dict[str, dict],
    captions: dict[str, str],
    title: str = "remaster report",
    audit: dict | None = None,
    comparison: dict | None = None,
    prediction: dict | None = None,
    failed: dict[str, str] | None = None,
) -> str:
    """The report of a run. campaigns: name -> {"summary": campaign summary dict, "certificate"
    (optional): its certificate.json, "tables": {table name: DataFrame}, "figures": {figure name:
    PNG bytes}}, shown in measurement-date order
    (then by name), so a robot's history reads forward as in the comparison;
    captions: table or figure name (figure names may end in _<sensor>) -> caption; comparison:
    {"tables": ..., "figures": ...} across campaigns; prediction: the same for the transfer table,
    its heat-maps and the comparisons by prediction (`PREDICTION_NOTES`); audit: the run's
    `audit.audit_record`, shown last; failed: {campaign: what failed} of the run's campaigns that did
    not reach their results (`results.failed_campaigns`), each a red row of the overview and nothing
    else: the report and the comparisons are of `campaigns` alone."""

    def caption(name: str) -> str:
        for key in sorted(captions, key=len, reverse=True):
            if name == key or name.startswith(key + "_"):
                suffix = name[len(key) + 1 :]
                return captions[key] + (f" ({suffix.replace('_', ' ')})" if suffix else "")
        return name.replace("_", " ")

    campaigns = dict(sorted(campaigns.items(), key=lambda item: (str(item[1]["summary"]["date"]), item[0])))
    failed = dict(sorted((failed or {}).items()))
    sections = _overview_section(overview(campaigns), failed)
    sections += [_campaign_section(name, content, caption) for name, content in campaigns.items()]
    intro = _intro(failed, len(campaigns))
    if comparison is not None:
        sections.append(
            Section(
                "Across campaigns and sensors",
                [
                    "Campaigns of the same robot in date order, and the sensors of each campaign, "
                    "compared in units of their combined uncertainty: the zero-offsets of the paper's "
                    "model, then the loop closure's model (the zero-offsets refitted with the effects "
                    "it added, and those effects' parameters)."
                ],
                [(caption(t), table) for t, table in comparison["tables"].items()],
                [(caption(f), png) for f, png in comparison["figures"].items()],
            )
        )
    if prediction is not None:
        sections.append(
            Section(
                "Transfer and comparison by prediction",
                list(PREDICTION_NOTES),
                [(caption(t), table) for t, table in prediction["tables"].items()],
                [(caption(f), png) for f, png in prediction["figures"].items()],
            )
        )
    if audit is not None:
        sections.append(audit_section(audit))
    return render(title, intro, sections)
