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


def _all_pairs_farthest(q):
    distances = np.linalg.norm(q[:, None] - q[None], axis=-1)
    return tuple(int(k) for k in np.unravel_index(np.argmax(distances), distances.shape))


@pytest.mark.parametrize("shape", ["cloud", "grid with ties and duplicates", "plane", "line", "one point"])
def test_the_farthest_pair_from_the_hull_is_the_all_pairs_answer(rng, shape):
    """Above ALL_PAIRS_UP_TO points the farthest pair is sought among the hull's vertices: the
    same pair as among all pairs, the first one on ties, in every degenerate shape."""
    n = registration.ALL_PAIRS_UP_TO + 500
    q = {
        "cloud": lambda: rng.normal(size=(n, 3)),
        "grid with ties and duplicates": lambda: np.round(rng.uniform(0, 4, (n, 3))),
        "plane": lambda: np.column_stack([rng.normal(size=(n, 2)), np.full(n, 0.3)]) @ spatial.rot_z(0.4).T,
        "line": lambda: np.outer(rng.normal(size=n), [1.0, 2.0, 3.0]),
        "one point": lambda: np.ones((n, 3)),
    }[shape]()
    assert registration.farthest_pair(q) == _all_pairs_farthest(q)


def test_the_spread_out_triple_of_100k_points_needs_no_pairwise_table(rng):
    """100,000 points (an all-pairs table would take 240 GB): a few MB."""
    import tracemalloc

    points = rng.normal(size=(100_000, 3))
    tracemalloc.start()
    triple = registration.spread_out_triple(points)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 100e6
    i, j = registration.farthest_pair(points)
    hull_distance = np.linalg.norm(points[i] - points[j])
    assert np.all(np.linalg.norm(points - points[i], axis=1) <= hull_distance)  # nothing is farther from i
    assert tuple(triple[:2]) == (i, j)


def test_a_stack_of_fits_is_the_registrations_kabsch_of_each(rng):
    reference = rng.uniform(-1, 1, (12, 3))
    targets = np.array(
        [
            spatial.transform_points(random_transform(rng), reference) + 1e-3 * rng.standard_normal((12, 3))
            for _ in range(4)
        ]
    )
    stacked = registration.rigid_transforms(reference, targets)
    assert stacked.shape == (4, 4, 4)
    for one, target in zip(stacked, targets):
        np.testing.assert_allclose(one, registration.kabsch(reference, target), atol=1e-12)
    # the single case is a call of the batched one: the same numbers, bit for bit
    weights = rng.uniform(0.5, 2.0, 12)
    assert np.array_equal(
        registration.kabsch(reference, targets[0], weights),
        registration.rigid_transforms(reference, targets[:1], weights / weights.sum())[0],
    )
    # several source sets, each onto its own target set: a reflection is never the answer
    mirrored = targets * np.array([1.0, 1.0, -1.0])
    rotations, _, _ = registration.rigid_fits(targets, mirrored)
    np.testing.assert_allclose(np.linalg.det(rotations), 1.0, atol=1e-12)


def test_one_model_set_registers_onto_many_as_its_copies_do(rng):
    """One model set (n, 3) against m target sets is centred once: the same rotations, centres and
    registered distances as the set repeated m times, and the distances are each target's own
    Kabsch residual."""
    from remaster.inference import metrics

    model = rng.uniform(-1, 1, (30, 3))
    targets = np.array(
        [spatial.transform_points(random_transform(rng), model) + 1e-3 * rng.standard_normal((30, 3)) for _ in range(5)]
    )
    copies = np.broadcast_to(model, targets.shape).copy()
    for one, repeated in zip(registration.rigid_fits(model, targets), registration.rigid_fits(copies, targets)):
        np.testing.assert_allclose(one, repeated, rtol=0, atol=1e-12)
    distances = metrics.registered_distances(model, targets)
    np.testing.assert_allclose(distances, metrics.registered_distances(copies, targets), rtol=0, atol=1e-12)
    for row, target in zip(distances, targets):
        own = spatial.transform_points(registration.kabsch(model, target), model) - target
        np.testing.assert_allclose(row, np.linalg.norm(own, axis=1), rtol=0, atol=1e-12)


def flange_poses(rng, n: int, turning: float = np.pi) -> np.ndarray:
    """n flange poses (n, 4, 4): positions in a 1.6 m cube, orientations within `turning` rad per Euler angle."""
    return np.array(
        [
            spatial.homogeneous(
                spatial.euler_zyx_to_matrix(*rng.uniform(-turning, turning, 3)), rng.uniform(-0.8, 0.8, 3)
            )
            for _ in range(n)
        ]
    )


def test_marker_and_registration_recovered_together(rng):
    """A remounted marker: the registration and the marker's true position come back from noiseless
    points, though the prior's centre is 0.5 mm off."""
    truth, marker = random_transform(rng), np.array([0.01, -0.02, 0.15])
    poses = flange_poses(rng, 40)
    sensor = spatial.transform_points(truth, poses[:, :3, :3] @ marker + poses[:, :3, 3])
    fitted, found = registration.kabsch_with_marker(poses, marker + [5e-4, -3e-4, 2e-4], sensor, 1e-9, 1e-3)
    np.testing.assert_allclose(found, marker, atol=1e-10)
    np.testing.assert_allclose(fitted, truth, atol=1e-9)


def test_marker_is_the_most_probable_under_its_prior(rng):
    """With noise, the pair is the posterior mode: the same as a direct minimisation of the
    9-parameter objective (scipy's least squares over the registration's rotation vector,
    translation and the marker, the prior as three residuals)."""
    from scipy.optimize import least_squares

    truth, marker, noise, std = random_transform(rng), np.array([0.0, 0.03, 0.1]), 2e-4, 5e-4
    poses = flange_poses(rng, 12, turning=0.3)  # little turning: the prior matters
    sensor = spatial.transform_points(truth, poses[:, :3, :3] @ marker + poses[:, :3, 3])
    sensor += rng.normal(0, noise, sensor.shape)
    prior = marker + [4e-4, 0.0, -4e-4]
    fitted, found = registration.kabsch_with_marker(poses, prior, sensor, noise, std)

    def residuals(x):
        transform = spatial.homogeneous(spatial.rotation_vector_to_matrix(x[:3][None])[0], x[3:6])
        points = poses[:, :3, :3] @ x[6:] + poses[:, :3, 3]
        return np.concatenate(
            [((spatial.transform_points(transform, points) - sensor) / noise).ravel(), (x[6:] - prior) / std]
        )

    start = np.concatenate([spatial.matrix_to_rotation_vector(truth[:3, :3][None])[0], truth[:3, 3], prior])
    direct = least_squares(residuals, start, xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    np.testing.assert_allclose(found, direct[6:], atol=1e-8)
    np.testing.assert_allclose(fitted[:3, 3], direct[3:6], atol=1e-8)


def test_one_tool_orientation_keeps_the_marker_given(rng):
    """Every pose with one orientation: a marker offset is a translation of the registration, so
    the marker stays at its prior centre and the registration takes the rest."""
    truth, rotation = random_transform(rng), spatial.euler_zyx_to_matrix(0.3, -0.2, 0.1)
    poses = np.array([spatial.homogeneous(rotation, p) for p in rng.uniform(-0.8, 0.8, (30, 3))])
    marker = np.array([0.0, 0.0, 0.1])
    sensor = spatial.transform_points(truth, poses[:, :3, :3] @ marker + poses[:, :3, 3])
    given = marker + [3e-4, 0.0, 0.0]
    fitted, found = registration.kabsch_with_marker(poses, given, sensor, 1e-5, 1e-3)
    np.testing.assert_allclose(found, given, atol=1e-12)
    residual = sensor - spatial.transform_points(fitted, poses[:, :3, :3] @ found + poses[:, :3, 3])
    assert np.abs(residual).max() < 1e-9
