"""Registration recovers known rigid transforms; degenerate point sets are refused."""

import numpy as np
import pytest

from remaster import spatial
from remaster.errors import InputError
from remaster.robot import registration


def random_transform(rng):
    return spatial.homogeneous(spatial.euler_zyx_to_matrix(*rng.uniform(-np.pi, np.pi, 3)), rng.uniform(-3, 3, 3))


@pytest.mark.parametrize("method", ["three_point", "kabsch"])
def test_recovers_known_transform_without_noise(rng, method):
    truth = random_transform(rng)
    robot = rng.uniform(-0.8, 0.8, (3 if method == "three_point" else 40, 3))
    sensor = spatial.transform_points(truth, robot)
    np.testing.assert_allclose(getattr(registration, method)(robot, sensor), truth, atol=1e-12)


def test_kabsch_is_least_squares_with_noise(rng):
    truth = random_transform(rng)
    robot = rng.uniform(-0.8, 0.8, (200, 3))
    sensor = spatial.transform_points(truth, robot) + rng.normal(0, 1e-4, (200, 3))
    fitted = registration.kabsch(robot, sensor)
    residual = np.linalg.norm(spatial.transform_points(fitted, robot) - sensor, axis=1)
    truth_residual = np.linalg.norm(spatial.transform_points(truth, robot) - sensor, axis=1)
    assert np.sum(residual**2) <= np.sum(truth_residual**2)
    assert np.abs(fitted - truth).max() < 1e-4
    assert np.linalg.det(fitted[:3, :3]) == pytest.approx(1.0)


def test_collinear_or_too_few_points_are_refused(rng):
    line = np.outer(np.linspace(0, 1, 5), [1.0, 2.0, 0.5])
    with pytest.raises(InputError, match="collinear"):
        registration.three_point(line[:3], line[:3])
    with pytest.raises(InputError, match="collinear"):
        registration.kabsch(line, line)
    with pytest.raises(InputError, match="at least 3"):
        registration.kabsch(line[:2], line[:2])
    with pytest.raises(InputError, match="non-finite.*row 1"):
        registration.kabsch(np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]), np.eye(3))
    with pytest.raises(InputError, match="one line"):
        registration.spread_out_triple(line)


def test_spread_out_triple_picks_far_apart_points(rng):
    points = rng.uniform(-0.1, 0.1, (50, 3))
    points[[7, 21, 40]] = [[1, 0, 0], [-1, 0, 0], [0, 1, 0]]
    points[3] = np.nan  # an unseen marker is skipped, not chosen
    assert sorted(registration.spread_out_triple(points)) == [7, 21, 40]
