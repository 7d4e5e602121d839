"""The zero-offsets' share of a residual field the model lacks: the field's variance through a
linear map against known answers, the sensitivity against a refit, and when it applies."""

import dataclasses

import numpy as np
import scipy.special

from remaster import noise
from remaster.inference import evidence
from remaster.inference.gp.kernels import Hyperparameters, kernel
from remaster.loop import loop_closure, model_error_share

from ..conftest import loop_report
from .test_loop_closure import EFFECTS, simulated
from .test_selection import _forced


def _field(lengthscale: float, signal: float = 2e-5) -> Hyperparameters:
    return Hyperparameters(np.full(3, lengthscale), signal, 0.0)


def test_the_fields_variance_through_a_mean_is_known_at_both_ends():
    """The mean of the x coordinates over n configurations: a field constant over the joints (long
    lengthscales) passes whole (variance s^2), a field independent from one configuration to the
    next (short lengthscales, configurations far apart) averages down to s^2 / n; in between, the
    chunked sum is the full diag(B K B^T)."""
    rng = np.random.default_rng(3)
    n = 40
    q = rng.uniform(-2.5, 2.5, (n, 3))
    mean_x = np.zeros((1, n, 3))
    mean_x[0, :, 0] = 1.0 / n
    signal = 2e-5
    assert np.isclose(model_error_share.field_variance(q, _field(1e6), mean_x)[0], signal**2, rtol=1e-9)
    assert np.isclose(model_error_share.field_variance(q, _field(1e-3), mean_x)[0], signal**2 / n, rtol=1e-6)
    rows = rng.normal(size=(4, n, 3))
    hyper = _field(0.7)
    full = kernel(q, q, hyper)
    expected = sum(np.einsum("mi,ij,mj->m", rows[:, :, a], full, rows[:, :, a]) for a in range(3))
    assert np.allclose(model_error_share.field_variance(q, hyper, rows, chunk=7), expected, rtol=1e-12)


def _joint_field(rng, n: int, lengthscales, amplitudes=(3e-4, 2e-4)) -> model_error_share.JointField:
    """Joints 1 and 3 of a 3-joint arm, with random directions (n, 3, 3) m/rad."""
    return model_error_share.JointField(
        np.array([0, 2]), np.array(amplitudes), np.array(lengthscales, dtype=float), rng.normal(size=(n, 3, 3))
    )


def test_a_joint_fields_variance_is_its_kernel_without_the_constant_through_the_map():
    """Against the covariance built entry by entry: e = sum_j a_j(q) f_j(q_j), f_j of the circle
    kernel s_j^2 exp(-(1 - cos d) / l_j^2) less its constant Fourier term s_j^2 e^-z I_0(z), z = 1 / l_j^2
    (a joint's error averaged over its turn is its zero-offset)."""
    rng = np.random.default_rng(5)
    n = 30
    q = rng.uniform(-3.0, 3.0, (n, 3))
    field = _joint_field(rng, n, (0.4, 1.3))
    rows = rng.normal(size=(4, n, 3))
    covariance = np.zeros((n, 3, n, 3))
    for j, s, length in zip(field.joints, field.amplitudes, field.lengthscales):
        z = 1.0 / length**2
        d = q[:, None, j] - q[None, :, j]
        k = s**2 * (np.exp(-(1.0 - np.cos(d)) * z) - scipy.special.ive(0, z))
        a = field.directions[:, :, j]
        covariance += np.einsum("ni,nk,kl->nikl", a, k, a)
    expected = np.einsum("mni,nikl,mkl->m", rows, covariance, rows)
    assert np.allclose(model_error_share.joint_field_variance(q, field, rows), expected, rtol=1e-9)


def test_a_joint_error_constant_over_the_turn_is_the_zero_offset_itself():
    """A joint error of a lengthscale far beyond the circle is a constant: the zero-offset, which
    leaves no error of it (u_model -> 0); a short one is not."""
    rng = np.random.default_rng(6)
    n = 25
    q = rng.uniform(-3.0, 3.0, (n, 3))
    rows = rng.normal(size=(2, n, 3))
    flat = model_error_share.joint_field_variance(q, _joint_field(rng, n, (1000.0, 1000.0)), rows)
    short = model_error_share.joint_field_variance(q, _joint_field(rng, n, (0.3, 0.3)), rows)
    assert np.all(flat < 1e-4 * short)


def test_the_joint_field_is_taken_only_where_the_evidence_prefers_that_form(iiwa):
    """`JointField.preferred` reads the joint-error form's report (degrees) only where it is
    preferred; the share then is the joint field's, named as such, the free kernel still reported
    (the declared model error's draws use it)."""
    joints = {
        "q2": {"amplitude_deg": 0.03, "lengthscale_rad": 0.8},
        "q4": {"amplitude_deg": 0.01, "lengthscale_rad": 2.0},
    }
    sensor = simulated(iiwa, "joint_compliance", *EFFECTS["joint_compliance"])
    (_, data, *_), fitted = _forced(iiwa, sensor, ())
    directions = np.random.default_rng(7).normal(size=(len(data.q), 3, 7))
    assert model_error_share.JointField.preferred({"preferred": "free", "joints": joints}, directions) is None
    assert model_error_share.JointField.preferred(None, directions) is None
    field = model_error_share.JointField.preferred({"preferred": "joint_error", "joints": joints}, directions)
    np.testing.assert_array_equal(field.joints, [1, 3])
    np.testing.assert_allclose(field.amplitudes, np.radians([0.03, 0.01]))
    hyper = Hyperparameters(np.full(7, 0.6), 3e-5, 1e-5)
    share = model_error_share.zero_offset_model_error(fitted, hyper, False, True, field)
    rows = np.array([i for i, n in enumerate(fitted.model.names) if n.startswith("zero_offsets.")])
    expected = np.sqrt(
        model_error_share.joint_field_variance(data.q, field, model_error_share.sensitivity(fitted, rows))
    )
    got = [share["parameters"][fitted.model.names[i]]["u_model_deg"] for i in rows]
    assert share["form"] == "joint_error" and share["joint_field"]["q2"]["lengthscale_rad"] == 0.8
    assert np.allclose(np.radians(got), expected) and share["kernel"] == hyper.report()
    assert model_error_share.zero_offset_model_error(fitted, hyper, False, True)["form"] == "free"


def test_a_joint_form_whose_lengthscale_ends_on_its_lower_bound_is_not_taken_and_says_why():
    """At the joint-error form's shortest lengthscale f_j takes up structure shorter than a joint
    error (the real UR10's and UR5's residuals end there): the free form is taken, and the share says why."""
    short = {
        "preferred": "joint_error",
        "joints": {
            "q2": {"amplitude_deg": 0.28, "lengthscale_rad": 0.05},
            "q4": {"amplitude_deg": 0.02, "lengthscale_rad": 0.4},
        },
    }
    assert model_error_share.JointField.at_lower_bound(short) == ["q2"]
    assert not model_error_share.JointField.taken(short)
    assert model_error_share.JointField.taken({**short, "joints": {"q4": short["joints"]["q4"]}})
    assert model_error_share.JointField.preferred(short, np.zeros((3, 3, 7))) is None
    (why,) = loop_closure.joint_form_not_taken({"joint_error_form": short}).values()
    assert "q2" in why and "free form" in why
    assert loop_closure.joint_form_not_taken({"joint_error_form": {**short, "preferred": "free"}}) == {}
    assert loop_closure.joint_form_not_taken(None) == {}


def _moved_as_predicted(fitted, data) -> tuple[np.ndarray, np.ndarray]:
    """(predicted, refitted) moves of the fit's free zero-offsets when a smooth field of a few um is
    added to its measured positions: the sensitivity times the field, and the refit from the same start."""
    q = data.q
    field = 4e-6 * np.stack([np.sin(q[:, 1]), np.cos(q[:, 3]), np.sin(q[:, 0] + q[:, 5])], axis=1)
    moved = fitted.model.on(dataclasses.replace(data, measured=data.measured + field))
    refit = evidence.posterior_mode(moved, fitted.theta).theta - fitted.theta
    rows = np.array([i for i, n in enumerate(fitted.model.names) if n.startswith("zero_offsets.")])
    return np.einsum("pna,na->p", model_error_share.sensitivity(fitted, rows), field), refit[rows]


def test_the_sensitivity_is_how_the_mode_moves_with_a_field_added(iiwa):
    """A smooth field of a few um added to the measured positions moves the zero-offset fit's mode
    by the sensitivity times the field, to first order (the refit from the same start)."""
    sensor = simulated(iiwa, "joint_compliance", *EFFECTS["joint_compliance"])
    (_, data, *_), fitted = _forced(iiwa, sensor, ())
    predicted, refit = _moved_as_predicted(fitted, data)
    assert np.allclose(predicted, refit, rtol=0.01, atol=0.005 * np.abs(refit).max())
    # a tracker's range/transverse noise: the field enters through the whitening W
    shaped = fitted.model.with_noise(noise.RangeTransverse(1.7))
    fitted = dataclasses.replace(fitted, mode=evidence.posterior_mode(shaped, fitted.theta))
    predicted, refit = _moved_as_predicted(fitted, data)
    assert np.allclose(predicted, refit, rtol=0.01, atol=0.005 * np.abs(refit).max())


def test_it_applies_where_the_calibration_carries_a_field_and_only_there(iiwa):
    assert model_error_share.applies(False, False) and model_error_share.applies(True, True)
    assert not model_error_share.applies(True, False) and not model_error_share.applies(None, False)
    sensor = simulated(iiwa, "joint_compliance", *EFFECTS["joint_compliance"])
    (_, data, *_), fitted = _forced(iiwa, sensor, ())
    closed = model_error_share.zero_offset_model_error(fitted, None, True, False)
    assert not closed["computed"] and "closed" in closed["why"]
    few_rows = fitted.model.on(data.subset(np.arange(len(data.q)) < 30))  # 30 configurations, 9 hyperparameters
    few = model_error_share.zero_offset_model_error(
        dataclasses.replace(fitted, mode=evidence.posterior_mode(few_rows, fitted.theta)), None, False, False
    )
    assert not few["computed"] and "30 configurations" in few["why"]
    (said,) = model_error_share.not_computed_warning(few, False, False)
    assert "30 configurations" in said and "understates" in said
    assert model_error_share.not_computed_warning(closed, True, False) == []
    # the compliance the model lacks leaves a field: its share is there for every free zero-offset
    share = model_error_share.zero_offset_model_error(fitted, None, False, False)
    free = [n for n in fitted.model.names if n.startswith("zero_offsets.")]
    assert share["computed"] and sorted(share["parameters"]) == sorted(free)
    assert all(p["u_model_deg"] > 0 for p in share["parameters"].values())


def test_the_declared_model_error_is_a_field_of_the_residuals_kernel_only_where_one_was_fitted():
    """`LoopReport.declared_field`: a loop not closed declares its structured residual per axis as
    the signal of the kernel its residual field was fitted with (no noise: the noise is the
    posterior's); a closed loop, or a field whose kernel was not fitted, declares no field."""
    kernel_report = _field(0.6, 3e-5).report()
    not_closed = {"rounds": [{"closed": False, "structured_mm": 0.12}]}
    share = {"computed": True, "kernel": {**kernel_report, "noise_std_m": 1e-5}}
    field = loop_report(closure=not_closed, model_error_share=share).declared_field()
    assert field.signal_std == 0.12e-3 and field.noise_std == 0.0
    np.testing.assert_array_equal(field.lengthscales, np.full(3, 0.6))
    closed = {"rounds": [{"closed": True, "structured_mm": 0.0}]}
    assert loop_report(closure=closed, model_error_share=share).declared_field() is None
    unfitted = {"computed": False, "why": "20 configurations"}
    assert loop_report(closure=not_closed, model_error_share=unfitted).declared_field() is None
    assert loop_report(closure=not_closed).declared_field() is None
