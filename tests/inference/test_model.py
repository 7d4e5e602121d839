"""The measurement model, its log-posterior and the identifiability analysis."""

import numpy as np
import pytest

from remaster import noise, spatial
from remaster.inference import blocks, identifiability
from remaster.inference.blocks import paper_model
from remaster.inference.model import SIGMA, correction_transforms, display_scale, parameter_names
from remaster.inference.parameter_blocks import BASE, block_parameters
from remaster.inference.readings import Readings
from remaster.robot import kinematics

from ..conftest import UR5_DH


def simulated(chain, rng, n=60, marker=(0.1, 0.0, 0.02), noise=0.0):
    """Readings, sensor-frame measurements from known zero-offsets and a known registration."""
    q = rng.uniform(np.maximum(chain.lower, -2.5), np.minimum(chain.upper, 2.5), (n, chain.n_joints))
    offsets = rng.normal(0.0, np.radians(0.3), chain.n_joints)
    t_nr = spatial.homogeneous(spatial.euler_zyx_to_matrix(2.0, 0.1, -0.2), [1.5, -0.3, 0.8])
    points = kinematics.marker_positions(chain, q + offsets, marker)
    measured = spatial.transform_points(t_nr, points) + rng.normal(0.0, noise, points.shape)
    return q, measured, np.array(marker), t_nr, offsets


def test_true_parameters_reproduce_noise_free_data(iiwa, rng):
    q, measured, marker, t_nr, offsets = simulated(iiwa, rng)
    model = paper_model(iiwa, q, measured, marker, t_nr)
    theta = np.concatenate([np.zeros(6), offsets])
    np.testing.assert_allclose(model.residuals(theta), 0.0, atol=1e-12)
    assert model.sum_squares(np.zeros(13)) > 1e-6


def test_registration_correction_composes_before_initial_transform(iiwa, rng):
    q, measured, marker, t_nr, offsets = simulated(iiwa, rng)
    correction = np.array([1e-3, -2e-3, 3e-3, 0.01, -0.02, 0.03])
    model = paper_model(iiwa, q, measured, marker, t_nr)
    expected = spatial.transform_points(
        spatial.homogeneous(spatial.euler_zyx_to_matrix(0.01, -0.02, 0.03), correction[:3]) @ t_nr,
        kinematics.marker_positions(iiwa, q + offsets, marker),
    )
    np.testing.assert_allclose(model.predict(np.concatenate([correction, offsets])), expected, atol=1e-12)
    np.testing.assert_allclose(correction_transforms(np.zeros(6)), np.eye(4))


def test_log_posterior_is_the_papers(iiwa, rng):
    q, measured, marker, t_nr, _ = simulated(iiwa, rng, n=30)
    model = paper_model(iiwa, q, measured, marker, t_nr)
    theta = rng.normal(0, 1e-3, 13)
    energy = np.sum((measured - model.predict(theta)) ** 2)
    for sigma in (1e-4, 1e-3):
        assert model.log_posterior(theta, sigma) == pytest.approx(
            -(3 * 30 + 2) * np.log(sigma) - energy / (2 * sigma**2)
        )
    assert model.log_posterior(theta, 0.0) == -np.inf and model.log_posterior(theta, -1.0) == -np.inf
    many = rng.normal(0, 1e-3, (5, 13))
    sigmas = np.array([1e-3, 2e-3, -1.0, 5e-4, 1e-3])
    np.testing.assert_allclose(
        model.log_posterior(many, sigmas), [model.log_posterior(t, s) for t, s in zip(many, sigmas)]
    )


def test_the_papers_model_sums_its_squares_compiled(iiwa, rng):
    """The paper's model (no extension block, isotropic noise) sums its squares in a compiled
    loop (`_kernels.registered_sum_squares`): its residuals' sum of squares to rounding, for one
    vector and a stack; a model with an extension block or a noise shape has no compiled path."""
    q, measured, marker, t_nr, _ = simulated(iiwa, rng, n=30, noise=1e-5)
    model = paper_model(iiwa, q, measured, marker, t_nr)
    assert model.blocks == BASE and model.compiled_posterior
    many = rng.normal(0, 1e-3, (4, 13))
    np.testing.assert_allclose(model.sum_squares(many), np.sum(model.residuals(many) ** 2, axis=(1, 2)), rtol=1e-12)
    assert model.sum_squares(many[1]) == model.sum_squares(many)[1]
    data = Readings(np.arange(len(q)), q, measured)
    assert not blocks.BlockModel(iiwa, data, marker, t_nr, ("sensor_scale",)).compiled_posterior
    shaped = model.with_noise(noise.RangeTransverse(1.0))
    assert not shaped.compiled_posterior
    with pytest.raises(ValueError, match="compiled walk"):
        shaped.metropolis_block(np.append(many[0], 1e-3), 0.0, np.zeros((2, 14)), np.zeros(2))
    with pytest.raises(ValueError, match="gravity torques"):
        blocks.BlockModel(iiwa, data, marker, t_nr, ("joint_compliance",))


@pytest.mark.parametrize("arm", ["iiwa", "ur5_dh"])
def test_the_expanded_sum_of_squares_is_the_sum_over_the_rows(arm, rng, request):
    """A campaign of many rows sums its squares from the expansion in the zero-offsets
    (`_kernels.expanded_sum_squares`): the sum over the rows (`registered_sum_squares`) at the
    expansion's reference, at the truth (a residual of the 10 um noise, where the log-posterior's
    differences are read: within a millionth of 2 sigma^2), near it and far from it, for 7 and 6
    joints, a zero-offset held."""
    from remaster import _kernels

    chain = request.getfixturevalue(arm)
    q, measured, marker, t_nr, offsets = simulated(chain, rng, n=800, noise=1e-5)
    model = paper_model(chain, q, measured, marker, t_nr, fixed={"zero_offsets.q1": offsets[0]})
    expansion = model._expansion()
    assert expansion[0].shape[0] == 3**chain.n_joints
    truth = np.concatenate([np.zeros(6), offsets[1:]])
    thetas = np.array(
        [np.zeros(len(truth)), truth, truth + rng.normal(0, 1e-6, len(truth)), truth + rng.normal(0, 1e-2, len(truth))]
    )
    every = model.full(thetas)
    summed = _kernels.registered_sum_squares(
        model._kernel.rotations,
        model._kernel.shifts,
        model._start,
        model._cos_q,
        model._sin_q,
        every,
        model.t_nr,
        model._measured_t,
    )
    expanded = model.sum_squares(thetas)
    np.testing.assert_allclose(expanded, summed, rtol=1e-9, atol=1e-6 * 2 * (1e-5) ** 2)
    assert summed[1] < 3 * len(q) * 2e-10  # at the truth, the noise's


def test_held_parameters_and_names(iiwa, rng):
    q, measured, marker, t_nr, offsets = simulated(iiwa, rng)
    model = paper_model(iiwa, q, measured, marker, t_nr, fixed={"zero_offsets.q1": offsets[0]})
    assert model.names == parameter_names(7)[:6] + parameter_names(7)[7:]
    np.testing.assert_allclose(model.residuals(np.concatenate([np.zeros(6), offsets[1:]])), 0.0, atol=1e-12)
    assert display_scale("registration.x") == 1e-3 and display_scale(SIGMA) == 1e-3
    assert display_scale("zero_offsets.q3") == pytest.approx(np.pi / 180)
    with pytest.raises(ValueError, match="does not have"):
        paper_model(iiwa, q, measured, marker, t_nr, fixed={"zero_offsets.q9": 0.0})
    with pytest.raises(ValueError, match="finite"):
        paper_model(iiwa, q, np.where(np.arange(len(q))[:, None] == 3, np.nan, measured), marker, t_nr)


def test_jacobian_matches_a_directional_difference(iiwa, rng):
    q, measured, marker, t_nr, _ = simulated(iiwa, rng, n=20)
    model = paper_model(iiwa, q, measured, marker, t_nr)
    theta, direction = rng.normal(0, 1e-3, 13), rng.normal(0, 1, 13)
    h = 1e-6
    numeric = (model.residuals(theta + h * direction) - model.residuals(theta - h * direction)).ravel() / (2 * h)
    np.testing.assert_allclose(model.jacobian(theta) @ direction, numeric, atol=1e-7)


def test_iiwa_has_exactly_one_degeneracy_joint_1_against_registration(iiwa, rng):
    q, measured, marker, t_nr, _ = simulated(iiwa, rng, noise=1e-5)
    result = identifiability.analyse(paper_model(iiwa, q, measured, marker, t_nr))
    assert list(result.held) == ["zero_offsets.q1"]
    assert len(result.null_directions) == 1
    assert set(result.null_directions[0]) <= {"zero_offsets.q1"} | {
        f"registration.{p}" for p in ("x", "y", "z", "alpha", "beta", "gamma")
    }
    assert result.singular_values[-1] < 1e-7 * result.singular_values[0]
    assert result.singular_values[-2] > 1e-3 * result.singular_values[0]  # nothing else is near-degenerate
    assert np.isfinite(result.condition_number) and result.condition_number < 1e4


def test_marker_on_last_axis_hides_its_offset(rng):
    """UR5 (a DH robot): with the marker on joint 6's axis that offset is invisible as well."""
    ur5 = kinematics.chain_from_dh(UR5_DH, "standard")
    q, measured, marker, t_nr, _ = simulated(ur5, rng, marker=(0.0, 0.0, 0.031))
    result = identifiability.analyse(paper_model(ur5, q, measured, marker, t_nr))
    assert sorted(result.held) == ["zero_offsets.q1", "zero_offsets.q6"]
    q, measured, marker, t_nr, _ = simulated(ur5, rng, marker=(0.05, 0.0, 0.031))
    assert list(identifiability.analyse(paper_model(ur5, q, measured, marker, t_nr)).held) == ["zero_offsets.q1"]


def test_a_massless_arms_compliance_is_its_gravity_regressor_and_predicts_as_the_arm_with_masses(iiwa, rng):
    """The iiwa without its inertials gets a coefficient per joint, body beyond it and regressor
    column; set to c_j times the URDF's masses and first moments (which the massless chain never
    sees) and the payload term to c_j, it predicts what the URDF's own compliance c_j predicts."""
    import dataclasses

    from remaster.calibration.prediction import Predictor

    bare = dataclasses.replace(iiwa, inertias=None)
    names = block_parameters("joint_compliance", bare).names
    assert len(names) == 4 * 28 + 7 and "joint_compliance.q2.body4.mx" in names
    assert "joint_compliance.q2" not in names and "joint_compliance.payload_q2" in names
    q = rng.uniform(np.maximum(iiwa.lower, -2.5), np.minimum(iiwa.upper, 2.5), (40, 7))
    compliance = rng.uniform(1e-5, 5e-5, 7)
    massed = Predictor(iiwa, q, (0.1, 0.0, 0.02), ("joint_compliance",))
    values = {f"joint_compliance.q{j + 1}": c for j, c in enumerate(compliance)}
    expected = massed.points(values)
    bodies = {f"joint_compliance.payload_q{j + 1}": c for j, c in enumerate(compliance)}
    for j, c in enumerate(compliance):
        for k in range(j, 7):
            body = iiwa.inertias[k]
            moments = dict(zip(("m", "mx", "my", "mz"), [body.mass, *(body.mass * body.com)]))
            bodies |= {f"joint_compliance.q{j + 1}.body{k + 1}.{name}": c * v for name, v in moments.items()}
    massless = Predictor(bare, q, (0.1, 0.0, 0.02), ("joint_compliance",))
    assert np.abs(expected - massed.points({})).max() > 1e-4  # the compliance moves the marker
    np.testing.assert_allclose(massless.points(bodies), expected, rtol=0, atol=1e-12)
