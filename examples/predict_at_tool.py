"""Where the calibrated UR5 puts a tool: predicted positions at a tool centre point 0.15 m beyond
the flange, with each prediction's 95 % bound, and the commands that put the tool on targets.

    python examples/predict_at_tool.py

`remaster.api.predict` and `compensate` are what `remaster predict` and `remaster compensate` run,
on a calibration made in-process (`api.calibrate` of the bundled data/raw/jacobi-ur5-gts3800, with
the reduced settings of calibrate_ur5.py: about a minute) instead of a results folder. Positions
are in the robot's base frame (m); corrections and bounds in mm.
"""

from pathlib import Path

import numpy as np

from remaster import api

CAMPAIGN = Path(__file__).resolve().parents[1] / "data" / "raw" / "jacobi-ur5-gts3800"
REDUCED = {
    "loop_closure": {"residual_gp": {"enabled": False}},
    "accuracy": {"draws": 300, "random_configurations": 300},
    "acceptance": {"draws": 300},
}
TOOL = (0.0, 0.0, 0.15)  # m, in the flange frame


def main() -> None:
    calibration = api.calibrate(CAMPAIGN, "laser_tracker", api.settings(REDUCED))
    q = calibration.campaign.sensors["laser_tracker"].q("validation")[:5]  # five commands, rad
    predicted = api.predict(calibration, q, tcp=TOOL, draws=500)
    print(f"tool {TOOL} m, loop-closed model ({', '.join(calibration.effects)}):")
    print(predicted[["x", "y", "z", "correction_mm", "bound95_mm"]].round(4).to_string())
    targets = predicted[["nominal_x", "nominal_y", "nominal_z"]].to_numpy()  # where the nominal model aims
    compensated = api.compensate(calibration, targets, tcp=TOOL, draws=500)
    reached = compensated["status"] == "reached"
    print(f"compensated: {int(reached.sum())} of {len(targets)} targets reached")
    print(f"largest joint change: {compensated['largest_change_deg'].max():.4f} deg")
    print(f"largest predicted error after compensation: {np.max(compensated['error_mm']):.4f} mm")


if __name__ == "__main__":
    main()
