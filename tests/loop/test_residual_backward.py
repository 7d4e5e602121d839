"""Parametric effects scored again with the residual model present (`backward.residual_backward_pass`):
once the residual GP is added, a block kept only because it absorbed part of what the GP explains is
removed, and a block the truth has stays. The truth is made by the simulator in its own form: a
cyclic transmission error of orders 3 and 4 (beyond the `joint_harmonics` block's orders 1-2, so only
the GP can take it) and, in the second case, a sensor whose scale is 1000 ppm off (a motion capture's
size of error). With q3 free this design confounds the scale with the cyclic error: the scale's fit
under independent noise is -160 ppm where the truth has none, and scoring it by its Laplace evidence
plus the GP's gain on its residuals kept it (+26 nats); integrated with the GP present it gains 4
nats and the cross-validation says no. A 300 ppm scale is not told apart here (+10.7 nats, 2.6
standard errors, below the t(4) threshold) and is not asserted on."""

import math

import numpy as np
import pytest

from remaster.campaigns.arm_kinds import iiwa_scenario, simulated_sensor
from remaster.inference import evidence, fit
from remaster.inference.readings import readings
from remaster.loop.backward import residual_backward_pass
from remaster.loop.candidates import GP
from remaster.loop.fitted import fit_blocks
from remaster.loop.residual_gp import gp_candidate
from remaster.loop.tracker_noise import choose_noise

from ..conftest import REPO, loop_settings

# joint, cycles per turn, amplitude deg, phase deg: orders the joint_harmonics block (1, 2) does not have
TERMS = ((2, 3.0, 0.03, 20.0), (4, 4.0, 0.03, -40.0))


def cyclic_truth() -> list[dict]:
    out = []
    for joint, cycles, amplitude, phase in TERMS:
        term = {"amplitude_deg": [0.0] * 7, "cycles_per_turn": [1.0] * 7, "phase_deg": [0.0] * 7}
        term["amplitude_deg"][joint - 1] = amplitude
        term["cycles_per_turn"][joint - 1] = cycles
        term["phase_deg"][joint - 1] = phase
        out.append(term)
    return out


def case(scale_error: float = 0.0, growth: float = 0.0, extensions=("sensor_scale",)):
    """The case fitted with `extensions` forced into the model, and the GP on what it leaves:
    (fitted arguments, held, folds, settings, data, current fit, GP candidate)."""
    spec = iiwa_scenario(
        "residual-backward",
        seed=8,
        truth={"cyclic_error": cyclic_truth()},
        plan={"q3": "free", "sets": {"optimization": {"poses": 24, "configurations": 120}}},
    )
    spec["sensors"]["laser_tracker"].update(scale_error=scale_error, transverse_growth_per_m=growth)
    spec["plan"]["sets"]["validation"] = {"poses": 4, "configurations": 16}
    chain, sensor = simulated_sensor(spec, "laser_tracker", REPO)
    registration = fit.register(chain, sensor)
    _, analysis, _ = fit.build_model(chain, sensor, registration.t_nr)
    settings = loop_settings(mcmc=None)
    data = readings(chain, sensor, "optimization", settings.model)
    poses = sensor.table.loc[data.rows, "pose"].to_numpy()
    folds = evidence.pose_folds(poses, settings.cv_folds)
    args = (chain, data, sensor.marker, registration.t_nr)
    current = fit_blocks(*args, extensions, analysis.held, folds, settings.priors)
    rotation = current.model.sensor_rotation(current.theta)
    gp = gp_candidate(current, data, rotation, folds, settings)
    return args, analysis.held, folds, settings, data, current, gp


def forced(scale_error: float):
    """`sensor_scale` forced into the model, scored again with the GP present."""
    args, held, folds, settings, _, current, gp = case(scale_error)
    return residual_backward_pass(*args, held, folds, settings, current, gp, ["sensor_scale"], number=3), current


@pytest.mark.parametrize(("scale_error", "kept"), [(0.0, False), (1.0e-3, True)])
def test_a_block_is_kept_with_the_gp_present_only_when_the_truth_has_it(scale_error, kept):
    (final, added, gp, rounds, removals), current = forced(scale_error)
    first = rounds[0]
    assert first["pass"] == "backward" and first["with"] == GP
    scores = first["scores"]["sensor_scale"]
    assert scores["passed"] is kept
    assert added == (["sensor_scale"] if kept else [])
    assert scores["evidence"] == "gp_joint"  # the parameters integrated with the GP (120 rows)
    if kept:
        assert final is current and not removals
        assert "sensor_scale.s" in final.model.names
    else:
        assert first["removed"] == "sensor_scale" and removals[0][0] == "without sensor_scale (residual_gp present)"
        assert "sensor_scale.s" not in final.model.names
        # the GP is refitted to what the model without it leaves
        np.testing.assert_allclose(gp.residuals, final.residuals() @ final.model.sensor_rotation(final.theta))


@pytest.mark.parametrize(("scale_error", "kept"), [(0.0, False), (1.0e-3, True)])
def test_through_inducing_inputs_the_gp_present_scores_decide_as_the_exact_ones(monkeypatch, scale_error, kept):
    """The same two cases with the exact size lowered below their 120 rows and 60 inducing inputs:
    the parameters are integrated with the GP through the inducing form, and the decisions stand."""
    from remaster.inference.gp import with_parameters

    monkeypatch.setattr(with_parameters, "MAX_ROWS", 50)
    monkeypatch.setattr(with_parameters, "INDUCING", 60)
    (_, added, _, rounds, _), _ = forced(scale_error)
    scores = rounds[0]["scores"]["sensor_scale"]
    assert scores["evidence"] == "gp_joint" and scores["gp_method"] == "titsias"
    assert scores["passed"] is kept and added == (["sensor_scale"] if kept else [])


@pytest.mark.parametrize(("growth", "chosen"), [(0.0, "isotropic"), (4.0, "range_transverse")])
def test_the_tracker_noise_is_chosen_for_what_the_residual_model_leaves(growth, chosen):
    """The simulator's tracker noise: isotropic, or its transverse std growing by 4 per metre of
    range; chosen with the GP present, the growth found is the truth's within its stated std (chosen
    on the parametric fit alone, before the GP, the same data give 0.73 per metre at +11.5 nats: the
    noise shape takes up some of the model error)."""
    _, _, folds, settings, data, current, gp = case(growth=growth, extensions=())
    fitted, report = choose_noise(current, folds, settings, data.q, gp.gp.hyper)
    assert report["chosen"] == chosen
    assert report["residual_model"].startswith("residual_gp present")
    if chosen == "range_transverse":
        assert fitted.model.noise is not None
        log_growth = math.log(report["transverse_growth_per_m"])
        assert abs(log_growth - math.log(growth)) < 3.0 * report["growth_std_log"]
    else:
        assert fitted is current and report["log_evidence_gain"] < settings.min_log_evidence_gain


@pytest.mark.parametrize(("growth", "chosen"), [(0.0, "isotropic"), (4.0, "range_transverse")])
def test_through_inducing_inputs_the_tracker_noise_is_chosen_as_by_the_dense_form(monkeypatch, growth, chosen):
    """The same cases with the dense size lowered below their 120 rows and 60 inducing inputs: the
    noise shape is compared with the GP present through the inducing form, and the choice stands. The
    growth found is not asserted: with 60, 90 and 110 inducing inputs of these 120 scattered rows it is
    0.73, 1.7 and 3.0 per metre against the dense form's 3.9 (truth 4): the projected GP carries less
    of the residual (lengthscale 0.4 rad on joint 2), and the noise's shape takes up the rest."""
    from remaster.inference.gp import with_parameters

    monkeypatch.setattr(with_parameters, "MAX_NOISE_ROWS", 50)
    monkeypatch.setattr(with_parameters, "NOISE_INDUCING", 60)
    _, _, folds, settings, data, current, gp = case(growth=growth, extensions=())
    _, report = choose_noise(current, folds, settings, data.q, gp.gp.hyper)
    assert report["residual_model"].startswith("residual_gp present (gp_joint through 60 inducing inputs")
    assert report["chosen"] == chosen
