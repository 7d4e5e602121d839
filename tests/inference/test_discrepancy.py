"""Model discrepancy: the pose-clustered sandwich against known answers. The drift z between fleet
copies of one robot whose model lacks an effect, a study over copies, is benchmarks/bench_discrepancy.py's."""

import numpy as np

from remaster.inference import discrepancy


def test_with_independent_residuals_it_is_the_least_squares_covariance():
    rng = np.random.default_rng(1)
    n, p, sigma = 3000, 4, 0.3
    jacobian = rng.normal(size=(3 * n, p))
    residuals = rng.normal(0.0, sigma, (n, 3))
    poses = np.arange(n) // 5
    expected = sigma**2 * np.linalg.inv(jacobian.T @ jacobian)
    covariance = discrepancy.sandwich_covariance(jacobian, residuals, poses)
    np.testing.assert_allclose(np.sqrt(np.diag(covariance)), np.sqrt(np.diag(expected)), rtol=0.1)
    np.testing.assert_allclose(covariance, expected, atol=0.15 * np.diag(expected).max())


def test_a_residual_shared_by_a_pose_widens_it():
    """Residuals with a part shared by the configurations of each pose, along a parameter's
    direction: the sandwich std of that parameter grows with the shared part (independent
    residuals of the same size leave it where it was)."""
    rng = np.random.default_rng(2)
    n_poses, per_pose = 200, 5
    jacobian = rng.normal(size=(3 * n_poses * per_pose, 2))
    poses = np.repeat(np.arange(n_poses), per_pose)
    stds = []
    for shared in (0.0, 0.5):
        offsets = rng.normal(0.0, shared, n_poses)[poses]  # each pose moves parameter 0 by its own amount
        residuals = jacobian[:, 0].reshape(-1, 3) * offsets[:, None] + rng.normal(0.0, 0.1, (len(poses), 3))
        stds.append(np.sqrt(np.diag(discrepancy.sandwich_covariance(jacobian, residuals, poses))))
    assert stds[1][0] > 3 * stds[0][0]
