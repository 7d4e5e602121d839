"""The zero-offsets' share of a residual field the model lacks: the field's variance through a
linear map against known answers, the sensitivity against a refit, and when it applies."""

import dataclasses

import numpy as np

from remaster import noise
from remaster.inference import evidence
from remaster.inference.gp.kernels import Hyperparameters, kernel
from remaster.loop import model_error_share

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
