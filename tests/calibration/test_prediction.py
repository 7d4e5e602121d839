"""The calibrated kinematics of one model (`remaster.calibration.prediction`): which joints a model
corrects in proportion to their reading."""

import pandas as pd

from remaster.calibration import prediction

OFFSETS = {f"zero_offsets.q{j + 1}": 0.001 * j for j in range(6)}


def test_the_joints_a_joint_scale_reads_on_the_line():
    """A joint scale s_j q_j is not periodic in joint j: the joints whose scale is estimated (in the
    posterior's columns) or held away from 0 are linear; one held at 0 corrects nothing, and a
    model without the block (the zero-offsets, compliance, harmonics) is periodic in every joint."""
    scales = {"joint_scale.q1": 2e-4, "joint_scale.q2": 0.0, "joint_scale.q3": 0.0, "joint_scale.q5": -1e-4}
    draws = pd.DataFrame({"joint_scale.q3": [1e-5, -1e-5], "joint_scale.q1": [2e-4, 2e-4]})
    loop = prediction.Calibration("loop", {**OFFSETS, **scales}, ("joint_scale",), draws=draws)
    assert loop.linear_joints == (0, 2, 4)
    assert prediction.Calibration("loop", {**OFFSETS, **scales}, ("joint_harmonics",)).linear_joints == ()
    assert prediction.Calibration("paper", OFFSETS).linear_joints == ()
