"""Every table of one campaign, in one job: the fit's, the paper's accuracy tables (beside the
paper's published numbers for its twin), the sensor comparison and ISO 9283, the loop closure's,
the workspace claims, the calibration's, the uncertainty budget and the certificate.

Tables only read result files (the edge is here): `files` maps a kind of result file to its path
for each sensor (`remaster.stage_inputs.by_sensor`). Kinds: summary (fit/summary.csv), laplace,
registration, metrics_<table> (metrics/<table>.csv), configuration_errors, loop_theoretical
(loop_closure/theoretical_accuracy.csv), loop (loop_closure.json), loop_table
(loop_closure/before_after.csv), loop_residuals, claims (workspace_accuracy.csv), workspace
(workspace.json), offsets (calibrated/controller_offsets.csv), cross_check (fit/cross_check.csv,
for the certificate's word on the samplers; optional), acceptance (acceptance.json, the validation set as
the acceptance test, for the certificate's verdict; optional).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import pandas as pd

from .. import files as result_files
from ..calibration import exports
from ..campaigns.campaign import Campaign
from ..evaluation import accuracy, budget, iso9283, workspace
from ..evaluation.acceptance import Acceptance
from ..inference.laplace_report import LaplaceReport
from ..loop.result import LoopReport
from . import certificate, tables, tables_loop

Files = Mapping[str, Mapping[str, str]]  # kind -> sensor -> path


@dataclass(frozen=True)
class Table:
    """One table as the writers take it: file stem name, content, caption (label = name)."""

    name: str
    frame: pd.DataFrame
    caption: str


@dataclass(frozen=True)
class CampaignTables:
    tables: list[Table]
    certificate: certificate.Certificate


def _each(files: Files, kind: str, read: Callable) -> dict:
    return {sensor: read(path) for sensor, path in files[kind].items()}


def _paper_rows(files: Files) -> dict[str, dict[str, pd.DataFrame]]:
    """table -> sensor -> the rows of the paper's accuracy tables (`accuracy.TABLE_NAMES`), with the
    loop-closed model's rows in the theoretical ones."""
    out = {}
    for name in accuracy.TABLE_NAMES:
        per_sensor = _each(files, f"metrics_{name}", result_files.read_csv)
        if name in workspace.THEORETICAL_TABLES:
            for sensor, path in files["loop_theoretical"].items():
                per_sensor[sensor] = workspace.with_loop_rows(per_sensor[sensor], result_files.read_csv(path), name)
        out[name] = per_sensor
    return out


def campaign_tables(campaign: Campaign, label: str, summary: dict, files: Files, beside_paper: bool) -> CampaignTables:
    """Every table of `campaign` (`label`: its folder name; `summary`: its summary.json) from the
    result files of each of its sensors; `beside_paper`: also each paper table beside the paper's
    published numbers (`<table>_vs_paper`)."""
    sensors = list(files["summary"])
    summaries = _each(files, "summary", result_files.read_csv)
    laplaces = _each(files, "laplace", LaplaceReport.read)
    loops = _each(files, "loop", LoopReport.read)
    errors = _each(files, "configuration_errors", result_files.read_csv)
    claims = _each(files, "claims", result_files.read_csv)
    workspaces = _each(files, "workspace", result_files.read_json)
    offsets = _each(files, "offsets", result_files.read_csv)
    cross_checks = _each(files, "cross_check", result_files.read_csv) if "cross_check" in files else {}
    acceptances = _each(files, "acceptance", Acceptance.read) if "acceptance" in files else {}
    paper_rows = _paper_rows(files)
    metrics = {s: {t: result_files.read_csv(files[f"metrics_{t}"][s]) for t in accuracy.TABLE_NAMES} for s in sensors}

    frames = {
        "zero_offsets": tables.zero_offsets_table(summaries),
        "registration_params": tables.registration_params_table(summaries, laplaces),
        **{name: accuracy.paper_table(rows) for name, rows in paper_rows.items()},
    }
    captions = {**tables.CAPTIONS}
    if beside_paper:
        for name, rows in paper_rows.items():
            frames[f"{name}_vs_paper"] = accuracy.paper_comparison(name, rows)
            captions[f"{name}_vs_paper"] = tables.CAPTIONS[name] + " Beside the paper's published values."
    frames.update(
        {
            "sensor_comparison": accuracy.sensor_comparison(summaries, metrics),
            "iso9283": iso9283.iso9283_table({s: campaign.sensors[s] for s in sensors}, errors),
            "iso9283_poses": iso9283.iso9283_poses_table(
                {s: campaign.sensors[s] for s in sensors}, errors, campaign.chain
            ),
            "loop_closure": tables_loop.campaign_table(_each(files, "loop_table", result_files.read_csv), loops),
            "loop_closure_test": tables_loop.closure_table(loops),
            "loop_candidates": tables_loop.candidates_table(loops),
            "loop_harmonics_terms": tables_loop.harmonics_table(loops),
            "workspace_accuracy": workspace.workspace_table(claims, workspaces),
            "workspace_warnings": workspace.warnings_table(workspaces),
            "controller_offsets": exports.offsets_table(offsets),
            "calibrated_files": exports.files_table(label, sensors, "dh" in campaign.robot, exports.ur_form(campaign)),
            "uncertainty_budget": budget.budget_table(acceptances),
        }
    )
    cert = certificate.certificate(
        summary,
        {
            s: certificate.CertificateInputs(
                laplaces[s],
                errors[s],
                result_files.read_parquet(files["loop_residuals"][s]),
                claims[s],
                workspaces[s],
                loops[s],
                offsets[s],
                cross_checks.get(s),
                acceptances.get(s),
            )
            for s in sensors
        },
    )
    frames.update(
        {
            f"certificate_{part}": table
            for part, table in (
                ("verdict", cert.verdicts),
                ("accuracy", cert.accuracy),
                ("corrections", cert.corrections),
            )
        }
    )
    return CampaignTables([Table(name, frame, captions[name]) for name, frame in frames.items()], cert)


def certificate_record(cert: certificate.Certificate) -> dict:
    """certificate.json: the campaign, the certificate's first screen (a line per sensor), the verdict's words
    per sensor (`Certificate.details`), heading and warnings."""
    return {
        "campaign": cert.campaign,
        "brief": cert.brief,
        "verdict_details": cert.details,
        "heading": cert.heading,
        "warnings": cert.warnings,
    }
