"""Nearness to the measured configurations, in how far the marker moves (`remaster.robot.nearness`):
lever arms against a closed form, the distance against the marker's real motion, the spacing and
the draws near the data, the circle of a revolute joint and the line of a joint read as such."""

import numpy as np
import pytest

from remaster.robot import nearness
from remaster.robot.kinematics import ForwardKinematics, chain_from_dh

MARKER = np.array([0.0, 0.0, 0.1])


def planar_arm():
    """Two revolute joints about parallel z axes, links of 0.5 and 0.3 m: the marker (at the flange
    origin plus 0.1 m along z) lies 0.8 m from joint 1's axis and 0.3 m from joint 2's when straight."""
    return chain_from_dh([[0.5, 0.0, 0.0, 0.0], [0.3, 0.0, 0.0, 0.0]], "standard", name="planar")


def test_lever_arms_of_a_planar_arm_are_its_reach_to_the_marker():
    chain = planar_arm()
    q = np.array([[0.0, 0.0], [0.0, np.pi / 2]])  # straight, then the elbow bent: 0.8 m, then sqrt(0.5^2 + 0.3^2)
    np.testing.assert_allclose(nearness.lever_arms(chain, q, MARKER), [0.8, 0.3], atol=1e-12)


def test_the_distance_bounds_the_markers_motion_to_first_order(iiwa, rng):
    """Small moves from measured configurations: the marker moves at most the stated distance
    (to first order), and not far less on average."""
    measured = rng.uniform(-1.0, 1.0, (50, 7))
    near = nearness.Nearness.of(iiwa, measured, MARKER)
    step = 1e-3 * rng.standard_normal((50, 7))
    moved = np.linalg.norm(
        ForwardKinematics(iiwa, measured + step).points(MARKER) - ForwardKinematics(iiwa, measured).points(MARKER),
        axis=1,
    )
    stated = np.abs(step) @ near.lever
    assert np.all(moved <= stated * 1.01)
    assert np.median(moved / stated) > 0.2


def test_the_data_are_inside_and_far_configurations_are_not(iiwa, rng):
    """A thin design (joints within 0.1 rad of one configuration and of another): its own
    configurations are inside, draws near them too, configurations across the box between the two
    clusters are outside."""
    a, b = np.zeros(7), np.full(7, 1.0)
    measured = np.concatenate([a + 0.1 * rng.uniform(-1, 1, (40, 7)), b + 0.1 * rng.uniform(-1, 1, (40, 7))])
    near = nearness.Nearness.of(iiwa, measured, MARKER)
    assert np.mean(near.inside(measured)) >= 0.95  # the spacing is the 95th percentile of the data's own
    drawn = near.draw(300, np.random.default_rng(1))
    assert near.inside(drawn).all()
    box = rng.uniform(measured.min(axis=0), measured.max(axis=0), (300, 7))
    assert np.mean(near.inside(box)) < 0.1
    # a joint on whose axis the marker lies has no lever arm: the draws leave it where it was measured
    held = nearness.Nearness(measured, np.append(near.lever[:6], 0.0), near.radius)
    q = held.draw(100, np.random.default_rng(2))
    assert np.isin(q[:, 6], measured[:, 6]).all()


def test_the_nearest_measured_configuration_is_the_brute_force_one(iiwa, rng):
    """The tree finds what comparing with every measured configuration finds: sum_j r_j |d_j|, d_j
    wrapped to [-pi, pi] (angles beyond pi included), a joint without a lever arm ignored; the
    spacing counts configurations that differ only in such a joint apart."""
    measured = rng.uniform(-4.0, 4.0, (300, 7))
    measured[:20, 6] = measured[20:40, 6]  # identical but for joint 7 ...
    measured[:20, :6] = measured[20:40, :6]
    lever = np.append(rng.uniform(0.1, 0.9, 6), 0.0)  # ... which does not move the marker
    queries = np.concatenate([rng.uniform(-7.0, 7.0, (200, 7)), measured[:5] + 2 * np.pi])
    near = nearness.Nearness(measured, lever, 0.0)
    wrapped = (queries[:, None, :] - measured[None] + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(near.distance(queries), (np.abs(wrapped) @ lever).min(axis=1), rtol=1e-12, atol=1e-12)
    own = np.abs((measured[:, None, :] - measured[None] + np.pi) % (2 * np.pi) - np.pi) @ lever
    own[own <= 1e-12] = np.inf
    np.testing.assert_allclose(near._nearest(measured, exclude_self=True), own.min(axis=1), rtol=1e-12)
    # a command no configuration reaches (NaN angles) has no distance, and no error
    assert np.isnan(near.distance(np.full((2, 7), np.nan))).all()


def test_one_turn_away_is_as_near_on_the_circle_and_far_for_a_joint_read_on_the_line(ur5_dh, rng):
    """A reading one turn from a measured one (q1 + 2 pi, as a UR reaches a pose again) is the
    measured configuration on the circle: the same distance, inside, no turn counted. A joint a
    model corrects in proportion to its reading (`linear`) takes the readings' own difference: there
    the same reading is 2 pi r_1 away and counted one turn, and the brute-force distance agrees."""
    measured = rng.uniform(-1.5, 1.5, (200, 6))
    queries = np.concatenate([measured[:10], rng.uniform(-1.5, 1.5, (20, 6))])
    turned = queries + [2 * np.pi, 0, 0, 0, 0, 0]
    circle = nearness.Nearness.of(ur5_dh, measured, MARKER)
    np.testing.assert_allclose(circle.distance(turned), circle.distance(queries), rtol=1e-9, atol=1e-12)
    assert circle.inside(turned[:10]).all() and not circle.turns(turned).any()

    line = nearness.Nearness.of(ur5_dh, measured, MARKER, linear=(0,))
    np.testing.assert_allclose(line.distance(queries[:10]), 0.0, atol=1e-12)
    assert not line.inside(turned).any()
    differences = turned[:, None, :] - measured[None]
    differences[..., 1:] = (differences[..., 1:] + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(line.distance(turned), (np.abs(differences) @ line.lever).min(axis=1), rtol=1e-9)
    turns = line.turns(turned)
    assert (turns[:10, 0] == 1).all() and not turns[:, 1:].any() and not line.turns(queries).any()
    assert (line.turns(queries - [4 * np.pi, 0, 0, 0, 0, 0])[:10, 0] == -2).all()
    # a joint read on the line is held or moved by its raw reading, a turn on the circle is no move
    assert line.differences(turned[0], queries[0])[0] == pytest.approx(2 * np.pi)
    assert circle.differences(turned[0], queries[0])[0] == pytest.approx(0.0, abs=1e-12)


def test_a_joint_without_a_lever_arm_read_on_the_line_counts_no_turn(ur5_dh, rng):
    """The marker on joint 6's axis: joint 6 does not move it, so its reading, on the line or not,
    neither makes a configuration far nor counts a turn."""
    measured = rng.uniform(-1.5, 1.5, (100, 6))
    near = nearness.Nearness.of(ur5_dh, measured, np.zeros(3), linear=(5,))
    assert near.lever[5] == pytest.approx(0.0, abs=1e-12)
    turned = measured[:5] + [0, 0, 0, 0, 0, 2 * np.pi]
    np.testing.assert_allclose(near.distance(turned), 0.0, atol=1e-12)
    assert not near.turns(turned).any()


def test_a_joints_range_on_the_circle_is_the_circle_less_its_widest_gap(rng):
    """Readings straddling +-pi span the short arc across it, readings a turn apart are one, one
    reading spans nothing, and readings spread over the circle span it less their widest gap."""
    straddling = np.radians([[170.0], [-175.0], [179.0], [-170.0]])
    start, arc = nearness.circle_arcs(straddling)
    assert np.degrees(start[0]) == pytest.approx(170.0) and np.degrees(arc[0]) == pytest.approx(20.0)
    np.testing.assert_allclose(nearness.circle_arcs(straddling + 2 * np.pi * np.array([[1], [-1], [0], [2]]))[1], arc)
    assert nearness.circle_arcs([[5.0]])[1][0] == 0.0
    spread = np.radians([[-100.0], [-40.0], [20.0], [150.0]])  # gaps 60, 60, 130 and 110 across +-180
    start, arc = nearness.circle_arcs(spread)
    assert np.degrees(start[0]) == pytest.approx(150.0) and np.degrees(arc[0]) == pytest.approx(230.0)
