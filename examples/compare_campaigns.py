"""Compare two campaigns of one robot: the KUKA iiwa calibrated in the bundled kuka-twin and
kuka-twin-2019 campaigns (the same arm measured twice by a laser tracker), by their zero-offsets
and by what they predict.

    python examples/compare_campaigns.py

`remaster.api.compare` makes the workflow's comparison tables from calibrations made in-process:
the drift of each loop-closed model's zero-offset between the campaigns (difference, combined std
and z-score, flagged beyond 3), and the drift of the predicted marker positions across the joint space against what the
two posteriors' own spread explains. Reduced settings (no residual Gaussian process, fewer
posterior draws and configurations) keep each calibration to well under a minute.
"""

from pathlib import Path

from remaster import api

REPO = Path(__file__).resolve().parents[1]
REDUCED = {
    "loop_closure": {"residual_gp": {"enabled": False}},
    "accuracy": {"draws": 200, "random_configurations": 200},
    "acceptance": {"draws": 200},
    "comparison": {"random_configurations": 200, "draw_pairs": 50},
}


def main() -> None:
    settings = api.settings(REDUCED)
    calibrations = []
    for name in ("kuka-twin-2019", "kuka-twin"):
        campaign = api.calibration.as_campaign(REPO / "data" / "raw" / name, REPO)  # a shared URDF
        calibrations.append(api.calibrate(campaign, "laser_tracker", settings))
        print(f"{name}: effects {', '.join(calibrations[-1].effects) or 'none'}; verdict {calibrations[-1].verdict}")
    tables = api.compare(*calibrations, settings=settings)
    # the loop-closed model's parameters carry its MCMC refit's std; the zero-offset model's table
    # (drift_between_campaigns) needs the paper sampler's, which calibrate does not run
    drift = tables["loop_parameter_drift"]
    offsets = drift[drift["block"] == "zero_offsets"]
    print("zero-offset drift (loop-closed model):")
    print(offsets[["parameter", "unit", "diff", "combined_std", "z", "flagged"]].round(4).to_string(index=False))
    predicted = tables["prediction_drift"]
    print("predicted positions, drift across the joint space:")
    print(
        predicted[["model", "mean_mm", "p95_mm", "aligned_mean_mm", "null_p95_of_aligned_mean_mm", "flagged"]]
        .round(4)
        .to_string(index=False)
    )


if __name__ == "__main__":
    main()
