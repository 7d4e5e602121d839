"""The loop closure's tables of a campaign, from its sensors' reports (`remaster.loop.report.LoopReport`):
before and after with the effects added, the closure test after every step, and every candidate's
scores. Numbers in the units their columns name (mm, %).
"""

from __future__ import annotations

import pandas as pd

from ..loop.report import LoopReport
from ..loop.sides import with_sides


def campaign_table(tables: dict[str, pd.DataFrame], reports: dict[str, LoopReport]) -> pd.DataFrame:
    """Before and after of every sensor of a campaign, with the effects each added, for the report."""
    frames = []
    for sensor, table in tables.items():
        added = with_sides(reports[sensor].effects_added)
        frames.append(table.assign(Sensor=sensor, **{"Effects added": added}))
    out = pd.concat(frames, ignore_index=True)
    first = ["Sensor", "Effects added"]
    return out[first + [c for c in out.columns if c not in first]]


def closure_table(reports: dict[str, LoopReport]) -> pd.DataFrame:
    """The closure test of every sensor: after each step, the cross-validated RMS per axis, the
    noise floor, their ratio, the share of the structured residual the step removed, the verdict;
    the last row of a sensor says where what is left lives (the residual GP's joints)."""
    rows = []
    for sensor, report in reports.items():
        test, gp = report.closure, report.residual_gp
        shares = test["share_of_structured_residual"]
        where = (
            "GP not tried"
            if gp is None
            else ", ".join(gp["depends_on"])
            if gp["structure_found"]
            else "no structure the GP can predict"
        )
        for k, step in enumerate(test["rounds"]):
            last = k == len(test["rounds"]) - 1
            rows.append(
                {
                    "Sensor": sensor,
                    "After": step["after"],
                    "CV RMS per axis (mm)": step["rms_per_axis_mm"],
                    "Noise floor (mm)": test["noise_floor_mm"],
                    "Ratio": step.get("ratio_to_floor"),
                    "Share removed (%)": (
                        100.0 * shares[step["after"]] if shares.get(step["after"]) is not None else None
                    ),
                    "Verdict": step["text"],
                    "Residual depends on": where if last else "",
                }
            )
    return pd.DataFrame(rows)


def candidates_table(reports: dict[str, LoopReport]) -> pd.DataFrame:
    """Every candidate's scores in every round, per sensor: evidence gain, cross-validated fall
    (pose-grouped, in standard errors), BIC gain, the fraction of the residual it explains, and
    whether it was added. A candidate `select` skipped (nothing of it identifiable) has no scores:
    NaN, and the reason in the last column. A laser tracker's range/transverse noise model
    (`remaster.noise`) gets a row of its own, after the rounds: its evidence gain, or why it was
    not offered."""
    rows = []
    nan = float("nan")
    for sensor, report in reports.items():
        for name, rounds in report.candidates.items():
            for entry in rounds:
                added = entry["round"] <= len(report.effects_added) and report.effects_added[entry["round"] - 1] == name
                skipped = "skipped" in entry
                rows.append(
                    {
                        "Sensor": sensor,
                        "Round": entry["round"],
                        "Candidate": name,
                        "Log evidence gain": entry.get("log_evidence_gain", nan),
                        "CV RMSE (mm)": entry.get("cv_rmse_mm", nan),
                        "CV fall (%)": 100.0 * entry.get("cv_gain", nan),
                        "CV fall / SE": entry.get("cv_mse_fall_in_se", nan),
                        "BIC gain": entry.get("bic_gain", nan),
                        "Explained (%)": 100.0 * entry.get("explained_fraction", nan),
                        "Added": f"skipped: {entry['skipped']}" if skipped else "yes" if added else "",
                    }
                )
        noise_model = report.noise_model or {}
        if noise_model.get("offered"):
            rows.append(
                {
                    "Sensor": sensor,
                    "Round": nan,
                    "Candidate": "noise: range/transverse",
                    "Log evidence gain": noise_model["log_evidence_gain"],
                    "CV RMSE (mm)": nan,
                    "CV fall (%)": nan,
                    "CV fall / SE": nan,
                    "BIC gain": nan,
                    "Explained (%)": nan,
                    "Added": "yes" if noise_model["chosen"] == "range_transverse" else "",
                }
            )
        elif noise_model.get("why") and noise_model["why"] != "not a laser tracker":
            rows.append(
                {
                    "Sensor": sensor,
                    "Round": nan,
                    "Candidate": "noise: range/transverse",
                    **{
                        k: nan
                        for k in (
                            "Log evidence gain",
                            "CV RMSE (mm)",
                            "CV fall (%)",
                            "CV fall / SE",
                            "BIC gain",
                            "Explained (%)",
                        )
                    },
                    "Added": f"not offered: {noise_model['why']}",
                }
            )
    return pd.DataFrame(rows)
