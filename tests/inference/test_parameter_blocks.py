"""What the parameter blocks share (`remaster.inference.parameter_blocks`)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from remaster.calibration.prediction import Predictor
from remaster.inference.parameter_blocks import MARKER_OFFSET, carried_by_marker_offset


@pytest.mark.parametrize("arm", ["iiwa", "ur5_dh"])
def test_the_last_joints_turn_is_a_marker_offset_at_every_configuration(arm, request):
    """The premise of `carried_by_marker_offset`, checked on a URDF and a DH arm: a marker 100 mm
    off the last axis, turned 0.6 deg by that joint's zero-offset, lands at every one of 30 random
    configurations where one constant marker offset puts it (to 1e-11 m), and that offset is the
    turn's (Rz(d) m - m about the axis)."""
    chain = request.getfixturevalue(arm)
    q = np.random.default_rng(3).uniform(-2.0, 2.0, (30, chain.n_joints))
    marker = np.array([-0.1, 0.03, 0.02])
    at = Predictor(chain, q, marker, ("marker_offset",))
    turned = at.points({f"zero_offsets.q{chain.n_joints}": 0.01})
    fit = least_squares(lambda o: (at.points(dict(zip(MARKER_OFFSET, o))) - turned).ravel(), np.zeros(3), xtol=1e-15)
    assert np.abs(fit.fun).max() < 1e-11
    np.testing.assert_allclose(np.linalg.norm(fit.x), 2 * np.hypot(*marker[:2]) * np.sin(0.005), rtol=1e-6)


def test_only_the_last_joint_and_only_with_a_free_marker_offset():
    held = {"zero_offsets.q1": 0.0, "zero_offsets.q7": 0.0}
    assert carried_by_marker_offset(7, held, [*MARKER_OFFSET, "zero_offsets.q2"]) == {"zero_offsets.q7"}
    assert carried_by_marker_offset(7, held, ["marker_offset.x", "marker_offset.y"]) == frozenset()
    assert carried_by_marker_offset(6, held, MARKER_OFFSET) == frozenset()
