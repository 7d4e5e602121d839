"""Plan a measurement campaign for the KUKA iiwa of the bundled kuka-twin campaign: the joint
configurations to command, as `remaster plan` writes them (docs/cli.md, docs/planning.md).

    python examples/plan_campaign.py

The paper's planner: Latin-hypercube poses with the tool's Z axis pointing at the sensor, every
inverse-kinematics solution of each (joint 3 held at 0), those outside the joint limits, below the
floor, self-colliding or with the marker hidden from the sensor discarded, in a nearest-neighbour
tour. A laser tracker 2 m in front of the robot and 1 m up; a marker 0.1 m beside the flange.
Printed: what was planned, and its first configurations in degrees.
"""

from pathlib import Path

import numpy as np

from remaster.campaigns.folders import read_campaign
from remaster.planning import plan

REPO = Path(__file__).resolve().parents[1]
CAMPAIGN = REPO / "data" / "raw" / "kuka-twin"
TRACKER = (2.0, 0.0, 1.0)  # m, in the robot's base frame
MARKER = (0.1, 0.0, 0.02)  # m, in the flange frame


def main() -> None:
    chain = read_campaign(CAMPAIGN, REPO).chain  # its URDF: data/robots/kuka_iiwa14.urdf
    options = plan.PlanOptions(marker=MARKER, set="optimization")
    planned = plan.paper_plan(chain, np.asarray(TRACKER), options, np.random.default_rng(0))
    table = planned.table
    print(f"{chain.n_joints}-joint iiwa, tracker at {TRACKER} m: {planned.summary}")
    degrees = [f"q{j + 1}_deg" for j in range(chain.n_joints)]
    print(table[["pose", *degrees]].head(5).round(1).to_string(index=False))
    q = table[[f"q{j + 1}" for j in range(chain.n_joints)]].to_numpy()
    moved = np.ptp(q, axis=0) / (chain.upper - chain.lower)
    print("share of each joint's range the plan moves through: " + ", ".join(f"{m:.2f}" for m in moved))


if __name__ == "__main__":
    main()
