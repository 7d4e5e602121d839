"""A tool's place on the flange from a calibration measured at one marker: the priors' split of the
marker's offset between its mount and the flange, against known answers and against the physical
model it conditions (mount, tool link translation and rotation drawn and composed, not the formula)."""

import numpy as np
import pytest

from remaster.calibration.tool_link import ToolSplit
from remaster.robot.kinematics import small_motion
from remaster.units import DEG, MM

MARKER = np.array([0.03, -0.01, 0.08])


def test_without_rotation_the_offset_splits_by_the_translation_priors():
    """s = t and o = u + t: gain s_t^2 / (s_u^2 + s_t^2), variance s_u^2 s_t^2 / (s_u^2 + s_t^2), at any point."""
    split = ToolSplit.of(MARKER, [0.1, 0.0, 0.2], 1 * MM, 2 * MM, 0.0)
    np.testing.assert_allclose(split.gain, 0.8 * np.eye(3), atol=1e-12)
    np.testing.assert_allclose(split.std, np.full(3, np.sqrt(0.8) * MM), rtol=1e-12)


def test_a_fixed_mount_carries_the_whole_offset_to_a_tool_at_the_marker():
    """With the mount exact (prior std 0), a tool at the marker moves exactly as the marker was
    measured to: the shift is the offset, nothing is left to the priors."""
    split = ToolSplit.of(MARKER, MARKER, 0.0, 1 * MM, 0.1 * DEG)
    np.testing.assert_allclose(split.gain, np.eye(3), atol=1e-9)
    assert np.all(split.std < 1e-9)


def test_the_split_is_the_conditional_of_the_physical_model():
    """Mount u, tool link motion (t, r) drawn from their priors and composed as the chain composes
    the tool link (F_tool D(t, r)): the least-squares regression of the tool's shift on the marker's
    offset, and what it leaves, are the split's gain and covariance."""
    rng = np.random.default_rng(3)
    point, stds = np.array([0.1, 0.05, 0.15]), (1 * MM, 1 * MM, 0.1 * DEG)
    count = 200_000
    mount = stds[0] * rng.standard_normal((count, 3))
    motion = np.concatenate([stds[1] * rng.standard_normal((count, 3)), stds[2] * rng.standard_normal((count, 3))], 1)
    moved = small_motion(motion)  # (count, 4, 4)
    offset = moved[:, :3, :3] @ MARKER + moved[:, :3, 3] - MARKER + mount
    shift = moved[:, :3, :3] @ point + moved[:, :3, 3] - point
    gain, *_ = np.linalg.lstsq(offset, shift, rcond=None)
    left = shift - offset @ gain
    split = ToolSplit.of(MARKER, point, *stds)
    np.testing.assert_allclose(gain.T, split.gain, atol=0.01)
    # sampling error of a covariance element at this count: about 0.3 % of the diagonal
    np.testing.assert_allclose(np.cov(left.T), split.covariance, atol=0.015 * split.covariance.max())


def test_draws_have_the_split_mean_and_covariance():
    split = ToolSplit.of(MARKER, [0.0, 0.0, 0.2], 1 * MM, 1 * MM, 0.1 * DEG)
    offset = np.array([0.4, -0.2, 0.3]) * MM
    draws = split.draw(np.tile(offset, (100_000, 1)), np.random.default_rng(5))
    np.testing.assert_allclose(draws.mean(axis=0), split.mean(offset), atol=0.01 * MM)
    np.testing.assert_allclose(np.cov(draws.T), split.covariance, atol=0.02 * split.covariance.max())


@pytest.mark.parametrize("point", [[0.0, 0.0, 0.0], [0.0, 0.0, 0.15], [0.1, 0.0, 0.1]])
def test_a_tool_off_the_marker_keeps_what_the_priors_allow(point):
    """At the benchmark's tools and the default priors (1 mm, 1 mm, 0.1 deg), the priors leave about
    0.7 mm per axis or more: a TCP's place relative to the marker is the priors', not the data's."""
    split = ToolSplit.of(MARKER, point, 1 * MM, 1 * MM, 0.1 * DEG)
    assert np.all(split.std > 0.65 * MM) and np.all(split.std < 1.0 * MM)
