"""Calibrate the bundled UR5 (data/raw/jacobi-ur5-gts3800: 1000 grid configurations measured by a
laser tracker, 20 random ones kept for validation) and print what the calibration found, the
zero-offset corrections to type into the controller with their expanded uncertainty, and the
acceptance test's verdict.

    python examples/calibrate_ur5.py

`remaster.api.calibrate` runs the workflow's stages in-process: registration, the zero-offset fit,
the loop closure (the effects the data support beyond the zero-offsets), the workspace claims and
the acceptance test on the validation set. The settings are the schema's defaults (those of
`snakemake -j2` without a config.yaml) but REDUCED: the residual Gaussian process not tried and 300
posterior draws for the claims and the test instead of 2000, which keeps the run near a minute (the
full settings, api.settings() alone, take several minutes).
"""

from pathlib import Path

from remaster import api
from remaster.evaluation import workspace

CAMPAIGN = Path(__file__).resolve().parents[1] / "data" / "raw" / "jacobi-ur5-gts3800"
REDUCED = {
    "loop_closure": {"residual_gp": {"enabled": False}},
    "accuracy": {"draws": 300, "random_configurations": 300},
    "acceptance": {"draws": 300},
}


def main() -> None:
    calibration = api.calibrate(CAMPAIGN, "laser_tracker", api.settings(REDUCED))
    report = calibration.loop.report
    print(f"campaign: {calibration.campaign.name}, sensor: {calibration.sensor}")
    print(f"effects added by the loop closure: {', '.join(calibration.effects) or 'none'}")
    print(
        f"validation RMSE: {report.validation_rmse_before_mm:.3f} mm with zero-offsets alone, "
        f"{report.validation_rmse_after_mm:.3f} mm with the effects"
    )
    across = workspace.claim_rows(calibration.claims, "loop", "random").iloc[0]  # registered, with noise
    print(f"workspace claim across the joint limits: 95 % of positions within {across['p95_bound_mm']:.3f} mm")
    print("corrections to add to the controller's zero (loop-closed model, with its other effects):")
    for _, row in calibration.corrections().iterrows():
        value = f"{row['correction_deg']:+.4f} deg, U {row['U_deg']:.4f} deg" if row["status"] == "estimated" else ""
        print(f"  {row['joint']}: {value or row['status']}")
    print(f"verdict: {calibration.verdict}")
    print(calibration.acceptance.diagnosis_text)


if __name__ == "__main__":
    main()
