"""The residual GP in joint-error form (`remaster.inference.gp.joint_error`, `remaster.loop.joint_form`):
on the simulator's cyclic transmission error of orders 3 and 4 on joints 2 and 4 (which the
joint_harmonics block's orders do not have) the joint-error form is preferred and names joints 2
and 4 only, where the free GP's relevance also names joint 1 and 3 (what a residual modelled in
the base frame shows). Its gradient: `tests/inference/test_gp_likelihood.py`."""

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
