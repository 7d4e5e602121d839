"""The loop closure's tables of a campaign, from its sensors' reports (`remaster.loop.result.LoopReport`):
before and after with the effects added, the closure test after every step, every candidate's
scores, and the joints' cyclic errors (joint_harmonics) named. Numbers in the units their columns name (mm, %).
"""

from __future__ import annotations

import pandas as pd

from ..loop.result import LoopReport
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
    """The closure test of every sensor: after each step, the cross-validated RMS per axis (pose
    folds, and blocks of poses contiguous in time: None where not computed), the noise floor, their ratio
    (to the held-out floor) and the ratio up to which the closure test calls it closed, the share of the
    structured residual the step removed, the verdict;
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
                    "Time-blocked CV RMS per axis (mm)": step.get("time_blocked_rms_per_axis_mm"),
                    "Noise floor (mm)": test["noise_floor_mm"],
                    "Ratio": step.get("ratio_to_floor"),
                    # the ratio a correct model reaches at the closure test's level with these folds and rows
                    "Closed up to ratio": step.get("closed_up_to_ratio"),
                    "Share removed (%)": (
                        100.0 * shares[step["after"]] if shares.get(step["after"]) is not None else None
                    ),
                    "Verdict": step["text"],
                    "Residual depends on": where if last else "",
                }
            )
    return pd.DataFrame(rows)


SCORE_COLUMNS = (
    "Log evidence gain",
    "CV RMSE (mm)",
    "CV fall (%)",
    "CV fall / SE",
    "CV fall per fold (%)",
    "Held-out regions (%)",
    "BIC gain",
    "Explained (%)",
)


def _fold_falls(entry: dict) -> str | float:
    """Each fold's fall of the held-out error (%), a fold whose fit departed named so (it decided
    nothing: `evidence.DEPARTED_RATIO`); NaN without per-fold scores."""
    if "cv_fold_falls" not in entry:
        return float("nan")
    departed = set(entry.get("cv_departed_folds") or ())
    return " / ".join("departed" if i in departed else f"{100.0 * f:.0f}" for i, f in enumerate(entry["cv_fold_falls"]))


def _why_not(entry: dict, step: dict) -> str:
    """A forward candidate not added: the criteria it missed (`scoring.shortfalls`), or that it
    passed and the round's added candidate gained more evidence; '' for a report without them."""
    if entry.get("why_not"):
        return f"no: {entry['why_not']}"
    added = step.get("added")
    return f"no: it passed, {added} gained more evidence this round" if entry.get("passed") and added else ""


def _region_falls(entry: dict) -> str | float:
    """Each held-out region's fall of the held-out error (%), per fold set ('joint_space: 99 / 89 (departed)
    / ...; tool_axis: ...'), departed folds marked (they count: `scoring.region_gain`); NaN without
    regions."""
    sets = entry.get("region_folds")
    if not sets:
        return float("nan")
    return "; ".join(
        f"{name}: "
        + " / ".join(
            f"{100.0 * f:.0f}" + (" (departed)" if i in set(scores["departed"]) else "")
            for i, f in enumerate(scores["fold_falls"])
        )
        for name, scores in sets.items()
    )


def _candidate_row(sensor: str, name: str, entry: dict, step: dict) -> dict:
    """A candidate's row of `candidates_table`: its scores in one round (`entry`) of the selection
    (`step`: the round as loop_closure.json's rounds record it)."""
    nan = float("nan")
    backward = step.get("pass") == "backward"
    verdict = (
        f"skipped: {entry['skipped']}"
        if "skipped" in entry
        else ("removed" if step.get("removed") == name else "kept")
        if backward
        else "yes"
        if step.get("added") == name
        else _why_not(entry, step)
    )
    return {
        "Sensor": sensor,
        "Round": entry["round"],
        "Pass": ("backward, GP present" if step.get("with") else "backward") if backward else "forward",
        "Candidate": name,
        "Log evidence gain": entry.get("log_evidence_gain", nan),
        "CV RMSE (mm)": entry.get("cv_rmse_mm", nan),
        "CV fall (%)": 100.0 * entry.get("cv_gain", nan),
        "CV fall / SE": entry.get("cv_mse_fall_in_se", nan),
        # why an effect was or was not taken: each fold's fall, which the statistic weighs alike
        "CV fall per fold (%)": _fold_falls(entry),
        # where it carries over: each region's fall when held out, the one it extrapolates worst to shown
        "Held-out regions (%)": _region_falls(entry),
        "BIC gain": entry.get("bic_gain", nan),
        "Explained (%)": 100.0 * entry.get("explained_fraction", nan),
        "Added": verdict,
    }


def _noise_row(sensor: str, noise_model: dict) -> dict | None:
    """The range/transverse noise model's row of `candidates_table`: its evidence gain when it was
    offered, why it was not for a laser tracker, None for any other sensor."""
    nan = float("nan")
    head = {"Sensor": sensor, "Round": nan, "Pass": "", "Candidate": "noise: range/transverse"}
    if noise_model.get("offered"):
        return {
            **head,
            **{k: nan for k in SCORE_COLUMNS},
            "Log evidence gain": noise_model["log_evidence_gain"],
            "Added": "yes" if noise_model["chosen"] == "range_transverse" else "",
        }
    if noise_model.get("why") and noise_model["why"] != "not a laser tracker":
        return {**head, **{k: nan for k in SCORE_COLUMNS}, "Added": f"not offered: {noise_model['why']}"}
    return None


def candidates_table(reports: dict[str, LoopReport]) -> pd.DataFrame:
    """Every candidate's scores in every round, per sensor: evidence gain, cross-validated fall
    (pose-grouped, in standard errors), BIC gain, the fraction of the residual it explains, and
    whether it was added; in the backward pass (`backward.backward_pass`) each added block's
    scores against the model without it, and whether it was removed (with the residual GP present
    in both once it is added: `backward.residual_backward_pass`). A candidate `select` skipped
    (nothing of it identifiable) has no scores: NaN, and the reason in the last column. A laser
    tracker's range/transverse noise model (`remaster.noise`) gets a row of its own, after the
    rounds: its evidence gain, or why it was not offered."""
    rows = []
    for sensor, report in reports.items():
        by_round = {r["round"]: r for r in report.rounds}
        for name, rounds in report.candidates.items():
            rows += [_candidate_row(sensor, name, entry, by_round[entry["round"]]) for entry in rounds]
        noise = _noise_row(sensor, report.noise_model or {})
        if noise is not None:
            rows.append(noise)
    return pd.DataFrame(rows)


def harmonics_table(reports: dict[str, LoopReport]) -> pd.DataFrame:
    """The joints' cyclic errors of every sensor whose loop added `joint_harmonics`
    (`remaster.loop.harmonics`): per joint and order the data see, the posterior amplitude and phase
    of A sin(k q + phase) (deg), the amplitude's std, the chi-square of (cos, sin) against 0 with its
    p-value and the threshold it is held to, and whether the pair is named; a sensor without the
    block gets one row saying so."""
    rows = []
    nan = float("nan")
    for sensor, report in reports.items():
        section = report.harmonics
        if section is None:
            rows.append({"Sensor": sensor, "Joint": "", "Order": nan, "Named": "joint_harmonics not added"})
            continue
        for term in section["terms"]:
            if not term["seen_by_data"]:
                continue
            rows.append(
                {
                    "Sensor": sensor,
                    "Joint": term["joint"],
                    "Order": term["order"],
                    "Amplitude (deg)": term["amplitude_deg"],
                    "Amplitude std (deg)": term["amplitude_std_deg"],
                    "Phase (deg)": term["phase_deg"],
                    "Chi-square (2 dof)": term["chi2"],
                    "p-value": term["p_value"],
                    "p threshold": section["p_threshold"],
                    "Named": "yes" if term["named"] else "",
                }
            )
    return pd.DataFrame(rows)
