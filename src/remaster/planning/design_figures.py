"""The workspace design's figure: the predicted bound against the number of configurations
(`remaster.planning.design.bound_table`), so that a user sees what each extra measurement buys.

Returns a matplotlib Figure (Agg backend); `remaster.files.write_figure` saves it. Axes in mm.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from ..reporting.figures import finished  # noqa: E402


def bound_curve(bounds: pd.DataFrame, title: str, target_mm: float | None = None) -> plt.Figure:
    """95th percentile and mean over the workspace of the predicted 95 % position bound (mm, log
    scale) against n, from n = 1 (the prior alone, n = 0, is off the scale); a robust design's
    expected RMS error with the discrepancy beside them; the target as a line."""
    shown = bounds[bounds["n"] >= 1]
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    ax.plot(shown["n"], shown["bound_p95_mm"], "-", color="tab:blue", label="95th percentile over the workspace")
    ax.plot(shown["n"], shown["bound_mean_mm"], "--", color="tab:green", label="mean over the workspace")
    if "expected_rms_mm" in shown:
        # the robust criterion's: the error model's own bound says nothing of what it lacks
        ax.plot(
            shown["n"],
            shown["expected_rms_mm"],
            "-",
            color="tab:orange",
            label="expected RMS per axis, with the discrepancy",
        )
    if target_mm is not None:
        ax.axhline(target_mm, color="tab:red", linewidth=0.8, label=f"target {target_mm:g} mm")
    ax.set_yscale("log")
    ax.set_xlabel("configurations measured")
    ax.set_ylabel("predicted error (mm)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return finished(fig, title)
