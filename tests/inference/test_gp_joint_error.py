"""The residual GP in joint-error form (`remaster.inference.gp.joint_error`, `remaster.loop.joint_form`):
on the simulator's cyclic transmission error of orders 3 and 4 on joints 2 and 4 (which the
joint_harmonics block's orders do not have) the joint-error form is preferred and names joints 2
and 4 only, where the free GP's relevance also names joint 1 and 3 (what a residual modelled in
the base frame shows); and its evidence from a cut Fourier series is the dense one. The evidences'
gradients: `tests/inference/test_gp_likelihood.py`."""

import pytest

from remaster.inference.gp import joint_error
from remaster.loop import joint_form

from ..loop.test_residual_backward import case


def test_the_cyclic_error_is_read_as_errors_of_joints_2_and_4():
    args, _, _, settings, data, current, gp = case(extensions=())
    chain, data, marker, t_nr = args
    mode = current.mode
    pseudo = mode.model.whitened(mode.residuals) + (mode.jacobian @ mode.theta).reshape(-1, 3)
    directions = joint_form.joint_directions(chain, data, marker, t_nr, current.values())
    found = joint_error.joint_error_form(
        data.q, pseudo, directions, mode.jacobian, mode.model._prior_precision, gp.gp.hyper, 5.0
    )
    report = found.report()
    assert report["preferred"] == "joint_error"
    assert report["named_joints"] == ["q2", "q4"]
    # the free GP, on the same residuals, relates them to joints the truth does not move
    relevance = dict(zip([f"q{j + 1}" for j in range(7)], gp.relevance()))
    assert {"q1", "q2"} <= {j for j, r in relevance.items() if r >= 0.5}
    # the noise the joint form leaves is the simulator's tracker noise (10 um per axis)
    assert 0.8e-2 < report["noise_std_mm"]["joint_error_form"] < 1.2e-2


def test_the_joint_form_from_its_fourier_features_is_the_dense_covariance():
    """The joint form's evidence from its cut Fourier series and sums taken once is the dense 3n x 3n
    evidence of sum_j s_j^2 K_j(q_j) a_j a_j^T + noise^2 I, down to the shortest lengthscale it allows,
    and its gradient is its derivative."""
    import math

    import numpy as np

    from remaster.inference.gp import likelihood
    from remaster.inference.gp.kernels import circle_distances

    rng = np.random.default_rng(1)
    n, joints = 50, 3
    q, directions = rng.uniform(-3.0, 3.0, (n, joints)), rng.normal(size=(n, 3, joints))
    jacobian, y, precision = rng.normal(size=(3 * n, 4)), rng.normal(size=3 * n), np.array([0.0, 1.0, 0.0, 3.0])
    log_z = joint_error._joint_objective(q, y, directions, jacobian, precision, np.arange(joints))
    shortest = joint_error.LENGTH_BOUNDS[0]
    x = np.array([0.2, -0.3, 0.1, math.log(0.3), math.log(1.5), math.log(shortest), math.log(0.8)])
    value, gradient = log_z(x)
    distances = circle_distances(q)
    covariance = math.exp(2 * x[-1]) * np.eye(3 * n)
    for j in range(joints):
        v = directions[:, :, j].ravel()
        shape = np.repeat(np.repeat(np.exp(-distances[j] / math.exp(2 * x[joints + j])), 3, 0), 3, 1)
        covariance += math.exp(2 * x[j]) * shape * np.outer(v, v)
    assert value == pytest.approx(likelihood.dense_log_evidence(y, jacobian, precision, covariance), rel=1e-9)
    for k in range(len(x)):
        step = 1e-5 * np.eye(len(x))[k]
        assert gradient[k] == pytest.approx((log_z(x + step)[0] - log_z(x - step)[0]) / 2e-5, rel=1e-4, abs=1e-6)


def test_above_its_rows_the_free_forms_evidence_is_titsias_bound_and_the_joints_are_still_named(monkeypatch):
    """The same cyclic error with the free form's search held to a third of the rows: the joint form
    on every row, the free form's evidence Titsias' bound at what the third found; the same verdict."""
    args, _, _, settings, data, current, gp = case(extensions=())
    chain, data, marker, t_nr = args
    mode = current.mode
    pseudo = mode.model.whitened(mode.residuals) + (mode.jacobian @ mode.theta).reshape(-1, 3)
    directions = joint_form.joint_directions(chain, data, marker, t_nr, current.values())
    monkeypatch.setattr(joint_error, "MAX_ROWS", len(data.q) // 3)
    monkeypatch.setattr(joint_error, "FEATURE_CHUNK", 17)  # the joint form's sums in many blocks
    found = joint_error.joint_error_form(
        data.q, pseudo, directions, mode.jacobian, mode.model._prior_precision, gp.gp.hyper, 5.0
    )
    report = found.report()
    assert report["rows"] == len(data.q) and report["free_form_evidence"].startswith("titsias")
    assert report["preferred"] == "joint_error" and report["named_joints"] == ["q2", "q4"]


def test_titsias_bound_with_every_row_inducing_is_the_free_forms_exact_evidence():
    """The free form's exact evidence (its objective) and Titsias' bound with the rows as inducing
    inputs are one number (the bound is exact there): the two are on the same footing above MAX_ROWS."""
    import math

    import numpy as np

    from remaster.inference.gp.kernels import Hyperparameters
    from remaster.inference.gp.with_parameters import titsias_log_evidence

    rng = np.random.default_rng(2)
    n, joints, p = 40, 3, 4
    q = rng.uniform(-3.0, 3.0, (n, joints))
    jacobian, y, precision = rng.normal(size=(n, 3, p)), rng.normal(size=(n, 3)), np.array([0.0, 1.0, 0.0, 3.0])
    x = np.array([math.log(0.7), math.log(1.2), math.log(0.4), math.log(0.9), math.log(0.5)])
    turned = np.arange(joints)
    exact = joint_error._free_objective(q, y.ravel(), jacobian.reshape(-1, p), precision, turned)(x)[0]
    hyper = Hyperparameters(np.exp(x[:joints]), math.exp(x[-2]), math.exp(x[-1]))
    assert titsias_log_evidence(q, y, jacobian, precision, hyper, inducing=n) == pytest.approx(exact, rel=1e-6)
    assert titsias_log_evidence(q, y, jacobian, precision, hyper, inducing=10) < exact
