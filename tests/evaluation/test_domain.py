"""The measured domain: each joint's interval of readings, the held joints, where the claims hold,
and the random configurations inside it."""

import dataclasses

import numpy as np
import pytest

from remaster.evaluation import domain
from remaster.inference import metrics
from remaster.units import DEG

MARKER = np.array([0.0, 0.0, 0.1])  # m, flange frame


def readings(iiwa, rng, fraction: float, held=(2,)) -> np.ndarray:
    """200 readings spanning `fraction` of each joint's range about its centre, the `held` joints
    at 10 deg, the extremes of every interval reached."""
    lower, upper = metrics.joint_space_bounds(iiwa)
    centre, half = 0.5 * (lower + upper), 0.5 * fraction * (upper - lower)
    q = rng.uniform(centre - half, centre + half, (200, 7))
    q[0], q[1] = centre - half, centre + half
    q[:, list(held)] = 10 * DEG
    return q


def test_the_intervals_are_the_readings_extremes_and_a_joint_never_moved_is_held(iiwa, rng):
    q = readings(iiwa, rng, 0.6, held=(2, 6))
    q[5:, 6] += 0.001 * DEG  # jitter below HELD_WIDTH: held too, at the middle of what it read
    measured = domain.MeasuredDomain.of(iiwa, q, MARKER)
    np.testing.assert_array_equal(measured.held, [False, False, True, False, False, False, True])
    np.testing.assert_allclose(measured.lower[:2], q[:, :2].min(axis=0))
    np.testing.assert_allclose(measured.upper[3:6], q[:, 3:6].max(axis=0))
    assert measured.lower[2] == measured.upper[2] == 10 * DEG
    assert measured.lower[6] == pytest.approx(10.0005 * DEG)
    np.testing.assert_allclose(np.delete(measured.range_fraction, [2, 6]), 0.6)
    assert not measured.covers_the_limits
    report = measured.report()
    assert report["held_joints"] == ["q3", "q7"] and report["joints"][2]["range_fraction"] == 0.0
    # the verdict says what falls short of the limits; the ranges themselves are "Valid for"
    assert measured.holds() == f"{domain.INSIDE} ({measured.short_text()})"
    assert "q3 held at 10 deg" in measured.holds() and "q7 held at 10 deg" in measured.holds()
    assert "(60 % of its range)" in measured.ranges_text()
    assert measured.short_text().startswith("q1 over 60 % of its range; q2 over 60 % of its range; q3 held at 10 deg")


def test_the_claims_hold_across_the_limits_only_when_every_joint_and_the_tool_covered_them(iiwa, rng):
    """90 % of every range and tool axes spread wide: across the limits; one joint short of 90 %,
    or (`readings` turn joints 5 and 6 widely) the tool held: inside the measured ranges."""
    wide = domain.MeasuredDomain.of(iiwa, readings(iiwa, rng, 0.95, held=()), MARKER)
    assert wide.tool_axis_spread_deg >= domain.MIN_TOOL_SPREAD_DEG
    assert wide.covers_the_limits and wide.holds() == domain.ACROSS
    short = readings(iiwa, rng, 0.95, held=())
    lower, upper = metrics.joint_space_bounds(iiwa)
    short[:, 3] = np.clip(short[:, 3], lower[3], lower[3] + 0.85 * (upper[3] - lower[3]))
    assert not domain.MeasuredDomain.of(iiwa, short, MARKER).covers_the_limits
    tool_held = domain.MeasuredDomain(wide.lower, wide.upper, wide.limits_lower, wide.limits_upper, 12.0, wide.nearness)
    assert not tool_held.covers_the_limits and tool_held.holds().startswith(domain.INSIDE)


def test_domain_configurations_lie_near_the_data_and_repeat(iiwa, rng):
    measured = domain.MeasuredDomain.of(iiwa, readings(iiwa, rng, 0.3), MARKER)
    q = measured.configurations("KUKA iiwa #1", 500, seed=7)
    assert q.shape == (500, 7)
    assert (q >= measured.limits_lower).all() and (q <= measured.limits_upper).all()
    assert (q[:, 2] == 10 * DEG).all()  # the held joint stays at its value
    assert measured.nearness.inside(q).all()
    np.testing.assert_array_equal(q, measured.configurations("KUKA iiwa #1", 500, seed=7))
    assert not np.array_equal(q, measured.configurations("KUKA iiwa #2", 500, seed=7))


def test_a_joint_whose_limits_span_turns_is_covered_on_the_circle(ur5_dh, rng):
    """A UR's joints turn +-2 pi: readings one turn apart are one configuration, so each joint's
    share of its range is of the circle. Joint 1 read over -308..-187 deg covers a third of the
    circle whether read there or a turn up; joint 2 read at +-(170..180) deg covers 20 deg across
    +-180 (not the 350 deg between its extremes); joints within limits of less than a turn keep
    the interval's share of the limits."""
    ur = dataclasses.replace(ur5_dh, lower=np.full(6, -2 * np.pi), upper=np.full(6, 2 * np.pi))
    q = rng.uniform(-np.pi, np.pi, (300, 6))
    q[:, 0] = rng.uniform(-308, -187, 300) * DEG
    q[:2, 0] = [-308 * DEG, -187 * DEG]
    q[:, 1] = rng.choice([-1, 1], 300) * rng.uniform(170, 180, 300) * DEG
    q[:4, 1] = [-180 * DEG, -170 * DEG, 170 * DEG, 180 * DEG]
    turned = q + [2 * np.pi, 0, 0, 0, 0, 0]
    fractions = [domain.MeasuredDomain.of(ur, x, MARKER).range_fraction for x in (q, turned)]
    np.testing.assert_allclose(fractions[0], fractions[1], rtol=1e-12)
    np.testing.assert_allclose(fractions[0][:2], [121 / 360, 20 / 360], rtol=1e-9)
    assert np.all((fractions[0][2:] > 0.95) & (fractions[0][2:] < 1.0))  # 300 readings over the circle: small gaps
    limited = dataclasses.replace(ur, lower=np.full(6, -np.radians(170)), upper=np.full(6, np.radians(170)))
    inside = np.clip(q, -np.radians(170), np.radians(170))
    np.testing.assert_allclose(
        domain.MeasuredDomain.of(limited, inside, MARKER).range_fraction, np.ptp(inside, axis=0) / np.radians(340)
    )
