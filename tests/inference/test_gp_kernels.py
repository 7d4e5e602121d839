"""The kernel of the GP family (`remaster.inference.gp.kernels`): its two forms are one kernel, written
out element by element, periodic in each joint, blind to a joint the data never turn."""

import numpy as np

from remaster.inference.gp.kernels import (
    Hyperparameters,
    circle_distances,
    covariance_with_noise,
    kernel,
    shape_from_distances,
    turned_joints,
)


def test_both_forms_are_the_kernel_written_out():
    rng = np.random.default_rng(3)
    q = rng.uniform(-3.0, 3.0, (25, 3))
    q[:, 2] = 0.4  # never turned
    hyper = Hyperparameters(np.array([0.5, 1.7, np.inf]), 2e-4, 1e-5)
    assert turned_joints(q).tolist() == [True, True, False]
    written = np.array(
        [
            [
                hyper.signal_std**2
                * np.exp(-sum((1.0 - np.cos(a[j] - b[j])) / hyper.lengthscales[j] ** 2 for j in (0, 1)))
                for b in q
            ]
            for a in q
        ]
    )
    np.testing.assert_allclose(kernel(q, q, hyper), written, rtol=1e-12)
    weights = 1.0 / hyper.lengthscales[:2] ** 2
    shape = shape_from_distances(circle_distances(q[:, :2]), weights)
    np.testing.assert_allclose(hyper.signal_std**2 * shape, written, rtol=1e-12)
    np.testing.assert_allclose(
        covariance_with_noise(q, hyper), written + hyper.noise_std**2 * np.eye(len(q)), rtol=1e-12
    )
    # one turn apart is the same angle; the joint never turned changes nothing
    turned = q + np.array([2.0 * np.pi, -2.0 * np.pi, 1.0])
    np.testing.assert_allclose(kernel(turned, q, hyper), written, rtol=1e-9)
