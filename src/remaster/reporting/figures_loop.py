"""Loop-closure figures: what each candidate effect would explain, and the errors before/after.

Every function takes arrays from `remaster.loop.loop_closure` and returns a matplotlib Figure (Agg
backend, no screen); `remaster.files.write_figure` saves it. Axes in mm.
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ..campaigns.campaign import SETS  # noqa: E402
from ..loop.scoring import Signature
from ..units import MM  # noqa: E402
from .figures import _grid, error_histogram_axes, finished, note  # noqa: E402

AXES = ("x", "y", "z")


def signatures(candidates: Mapping[str, Signature], title: str) -> plt.Figure:
    """Per candidate: the current fit's residual (mm) against the change in prediction the
    candidate's fit makes (mm), one dot per point and axis. On the diagonal: the candidate is
    what the residual holds; a flat cloud: it explains nothing."""
    fig, axes = _grid(max(len(candidates), 1))
    for ax, (name, signature) in zip(axes, candidates.items()):
        effect, residual = signature.effect / MM, signature.residual / MM
        for k, axis in enumerate(AXES):
            ax.scatter(effect[:, k], residual[:, k], s=4, alpha=0.6, label=axis)
        limit = max(np.abs(residual).max(), np.abs(effect).max(), 1e-9)
        ax.plot([-limit, limit], [-limit, limit], color="k", lw=0.8)
        ax.set_xlim(-limit, limit)
        ax.set_ylim(-limit, limit)
        ax.set_title(f"{name}: explains {100 * signature.explained:.0f} %", fontsize=9)
        ax.set_xlabel("candidate's effect (mm)", fontsize=8)
        ax.set_ylabel("residual (mm)", fontsize=8)
        ax.tick_params(labelsize=7)
    if candidates:
        axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def residual_histograms(residuals: Mapping[str, Mapping[str, np.ndarray]], title: str) -> plt.Figure:
    """Post-registration errors |E_i| (mm) per set, before (zero-offset model) and after (with
    the effects added), on a logarithmic axis: the two may differ by orders of magnitude.
    residuals: {'before'|'after': {set: (n, 3) m}}."""
    fig, axes = plt.subplots(1, len(SETS), figsize=(4.2 * len(SETS), 3.0), squeeze=False)
    none = np.empty((0, 3))  # a set without rows (a campaign without a validation set)
    norms = {when: {s: np.linalg.norm(residuals[when].get(s, none), axis=1) / MM for s in SETS} for when in residuals}
    every = np.concatenate([v for per_set in norms.values() for v in per_set.values()])
    positive = every[every > 0]
    low, high = (positive.min(), positive.max()) if positive.size else (1e-3, 1.0)
    bins = np.geomspace(low, high * 1.0001, 40)
    for ax, set_name in zip(axes[0], SETS):
        for when, color in (("before", "tab:red"), ("after", "tab:blue")):
            values = norms[when][set_name]
            if not values.size:
                ax.text(0.5, 0.5, f"no {set_name} rows", transform=ax.transAxes, ha="center", fontsize=8)
                continue
            ax.hist(
                values, bins=bins, color=color, alpha=0.6, label=f"{when}: RMSE {np.sqrt(np.mean(values**2)):.3g} mm"
            )
        ax.set_xscale("log")
        error_histogram_axes(ax, set_name)
    return finished(fig, title)


def workspace_claims(claims: pd.DataFrame, title: str) -> plt.Figure:
    """Claimed error (mm, log axis) of each model, mean with its 95 % interval, at the measured
    configurations, at random ones inside the measured joint ranges and across the joint limits,
    registration fitted (filled) and in the robot frame with the held zero-offsets at the
    controller's tolerance (open). claims: `workspace.CLAIM_COLUMNS` rows."""
    fig, ax = plt.subplots(figsize=(7.0, 3.0))
    chosen = claims[claims["noise"] == "with noise"]
    labels = []
    names = {"optimization": "measured", "domain": "in ranges", "random": "limits"}
    for k, (model, where) in enumerate([(m, w) for m in ("paper", "loop") for w in names]):
        labels.append(f"{model}\n{names[where]}")
        for offset, frame, fill in ((-0.12, "registered", True), (0.12, "robot", False)):
            r = chosen[
                (chosen["model"] == model) & (chosen["configurations"] == where) & (chosen["frame"] == frame)
            ].iloc[0]
            color = "tab:red" if model == "paper" else "tab:blue"
            ax.errorbar(
                k + offset,
                r["mean_mm"],
                yerr=[[r["mean_mm"] - r["q2.5_mm"]], [r["q97.5_mm"] - r["mean_mm"]]],
                fmt="o",
                color=color,
                mfc=color if fill else "white",
                capsize=3,
                label=("registration fitted" if fill else "robot frame, held joints at tolerance") if k == 0 else None,
            )
    ax.set_xticks(range(len(labels)), labels, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("claimed error (mm)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7)
    return finished(fig, title)


def residual_by_joint(rows: pd.DataFrame, gp: Mapping | None, title: str) -> plt.Figure:
    """The residual the parametric effects leave (robot frame, mm) against the joint the residual
    GP finds most relevant (deg), per axis, with its median in 30 bins; rows: the GP's training
    rows (`loop_candidate.training_frame`), gp: loop_closure.json's `residual_gp` section."""
    if rows.empty or gp is None:
        return note("residual GP not tried", title)
    fig, ax = plt.subplots(figsize=(6.0, 3.0))
    joint = gp["most_relevant_joint"] or max(gp["relevance"], key=gp["relevance"].get)
    angle = np.degrees(rows[joint].to_numpy(float))
    edges = np.linspace(angle.min(), angle.max() + 1e-9, 31)
    which = np.digitize(angle, edges) - 1
    for axis in AXES:
        values = rows[f"r{axis}"].to_numpy(float) / MM
        points = ax.scatter(angle, values, s=3, alpha=0.35, label=axis)
        medians = [np.median(values[which == b]) if np.any(which == b) else np.nan for b in range(30)]
        ax.plot(0.5 * (edges[:-1] + edges[1:]), medians, color=points.get_facecolor()[0], alpha=1.0, lw=1.5)
    found = "depends on " + ", ".join(gp["depends_on"]) if gp["structure_found"] else "no structure the GP can predict"
    ax.set_title(f"{found}; structured {100 * gp['structured_fraction']:.0f} %", fontsize=9)
    ax.set_xlabel(f"{joint} (deg)", fontsize=8)
    ax.set_ylabel("residual, robot frame (mm)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, markerscale=3)
    return finished(fig, title)


def harmonic_functions(section: Mapping | None, title: str) -> plt.Figure:
    """Each named joint's cyclic error f_j (deg, against the joint's reading over its measured range,
    deg): the posterior mean with its 95 % band, one panel per joint, the named orders in its title.
    section: loop_closure.json's `harmonics` (`remaster.loop.harmonics`), None when the block was not
    added."""
    functions = (section or {}).get("functions") or {}
    if not functions:
        return note("joint_harmonics not added" if section is None else "no joint's harmonics named", title)
    fig, axes = _grid(len(functions))
    for ax, (joint, function) in zip(axes, functions.items()):
        angle = np.asarray(function["angle_deg"])
        ax.fill_between(
            angle, function["q2.5_deg"], function["q97.5_deg"], color="tab:blue", alpha=0.3, label="95 % band"
        )
        ax.plot(angle, function["mean_deg"], color="tab:blue", lw=1.2, label="posterior mean")
        ax.axhline(0.0, color="k", lw=0.6)
        orders = ", ".join(str(k) for k in section["named"].get(joint, []))
        ax.set_title(f"{joint}: orders {orders} ({function['band_from']})", fontsize=9)
        ax.set_xlabel(f"{joint} reading (deg)", fontsize=8)
        ax.set_ylabel("f_j: angle error (deg)", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0].legend(fontsize=7)
    return finished(fig, title)
