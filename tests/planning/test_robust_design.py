"""The robust design criterion (planning/robust_design.py) against answers it does not compute:
a Monte-Carlo of the calibration with a discrepancy drawn as a Gaussian process and fitted by least
squares, the criterion's full-matrix form, brute-force greedy steps, and the straight line's known
designs."""

import numpy as np
import pytest

from remaster.planning import design_posterior as dp
from remaster.planning import robust_design as dd

from ..conftest import assert_documents_show

SIGMA = 1e-5  # m


def toy(rng, p=6, c=40, e=25, n_joints=3):
    """Candidates, workspace and Jacobians (smooth in q, m per display unit) of a made-up model."""
    q_candidates = rng.uniform(-2, 2, (c, n_joints))
    q_eval = rng.uniform(-2, 2, (e, n_joints))
    mixing = rng.normal(size=(2 * n_joints, 3 * p))

    def jacobian(q):
        return (np.concatenate([np.sin(q), np.cos(q)], axis=1) @ mixing).reshape(-1, 3, p) * 1e-3

    return q_candidates, q_eval, jacobian(q_candidates) / SIGMA, jacobian(q_eval), np.eye(p) * 1e-2


def test_the_expected_error_is_that_of_least_squares_fits_with_a_simulated_discrepancy():
    """Draw theta from the prior, the discrepancy from its GP jointly at the design and the workspace,
    the noise; fit the MAP by least squares on the stacked system; the mean squared error at the
    workspace over draws matches the criterion within its Monte-Carlo error."""
    rng = np.random.default_rng(1)
    q_c, q_e, jc, je, prior = toy(rng)
    q_d, jd = q_c[:12], jc[:12]
    discrepancy = dd.Discrepancy(np.array([0.8, 1.2, np.inf]), 3 * SIGMA)
    expected = dd.expected_squared_errors(jd, q_d, prior, je, q_e, discrepancy, SIGMA)
    p, n, e = prior.shape[0], len(q_d), len(q_e)
    q_all = np.vstack([q_d, q_e])
    k_all = discrepancy.kernel(q_all, q_all) + 1e-12 * discrepancy.signal_std**2 * np.eye(n + e)
    lower = np.linalg.cholesky(k_all)
    prior_root = np.linalg.cholesky(np.linalg.inv(prior))
    a = np.vstack([jd.reshape(-1, p), np.linalg.cholesky(prior).T])  # [Jw; P^1/2]: the MAP's stacked system
    draws, total = 4000, np.zeros(e)
    for _ in range(draws):
        theta = prior_root @ rng.normal(size=p)
        delta = lower @ rng.normal(size=(n + e, 3))  # (n + e, 3): the same kernel on each axis
        y = (jd.reshape(-1, p) * SIGMA) @ theta + delta[:n].ravel() + SIGMA * rng.normal(size=3 * n)
        theta_hat = np.linalg.lstsq(a, np.concatenate([y / SIGMA, np.zeros(p)]), rcond=None)[0]
        error = (je @ (theta_hat - theta)) - delta[n:]
        total += np.sum(error**2, axis=1)
    simulated = total / draws
    assert np.mean(simulated) == pytest.approx(np.mean(expected), rel=0.05)
    np.testing.assert_allclose(simulated, expected, rtol=0.15)


def test_without_a_discrepancy_it_is_the_posterior_alone():
    rng = np.random.default_rng(2)
    q_c, q_e, jc, je, prior = toy(rng)
    none = dd.Discrepancy(np.array([1.0, 1.0, 1.0]), 0.0)
    sigma_matrix = dp.covariance(prior + dp.information(jc[:10]))
    np.testing.assert_allclose(
        dd.expected_squared_errors(jc[:10], q_c[:10], prior, je, q_e, none, SIGMA),
        np.trace(dp.position_covariances(je, sigma_matrix), axis1=1, axis2=2),
        rtol=1e-10,
    )


def test_the_greedy_scores_are_the_full_matrices_and_each_step_the_best():
    rng = np.random.default_rng(3)
    q_c, q_e, jc, je, prior = toy(rng)
    discrepancy = dd.Discrepancy(np.array([0.7, 1.0, np.inf]), 2 * SIGMA)
    chosen = dd.robust_design(jc, q_c, je, q_e, prior, discrepancy, SIGMA, budget=8)
    assert chosen.criterion == "robust" and chosen.statistic == "rms" and len(chosen.chosen) == 8
    for n in range(len(chosen.chosen) + 1):
        rows = list(chosen.chosen[:n])
        direct = dd.expected_squared_errors(jc[rows], q_c[rows], prior, je, q_e, discrepancy, SIGMA)
        assert chosen.bounds["expected_rms_mm"].iloc[n] == pytest.approx(np.sqrt(direct.mean() / 3) / 1e-3, rel=1e-6)
        if n < len(chosen.chosen):
            left = [c for c in range(len(q_c)) if c not in rows]
            totals = [
                dd.expected_squared_errors(jc[rows + [c]], q_c[rows + [c]], prior, je, q_e, discrepancy, SIGMA).sum()
                for c in left
            ]
            assert left[int(np.argmin(totals))] == chosen.chosen[n]
    assert chosen.final_bound_mm == chosen.bounds["expected_rms_mm"].iloc[-1]


def test_a_target_stops_the_choice():
    rng = np.random.default_rng(4)
    q_c, q_e, jc, je, prior = toy(rng)
    discrepancy = dd.Discrepancy(np.array([0.7, 1.0, 1.0]), SIGMA)
    full = dd.robust_design(jc, q_c, je, q_e, prior, discrepancy, SIGMA, budget=15)
    target = full.bounds["expected_rms_mm"].iloc[6] * 1e-3
    stopped = dd.robust_design(jc, q_c, je, q_e, prior, discrepancy, SIGMA, target=target)
    assert stopped.stopped == "target" and len(stopped.chosen) == 6
    np.testing.assert_array_equal(stopped.chosen, full.chosen[: len(stopped.chosen)])


def line(x):
    """A straight line's Jacobian (n, 3, 2) in one axis: offset and slope, m per display unit."""
    j = np.zeros((len(x), 3, 2))
    j[:, 0, 0], j[:, 0, 1] = 1e-3, 1e-3 * x
    return j


def test_a_straight_line_is_measured_at_its_ends_unless_it_may_bend():
    """The known answers for a line on [-1, 1]: with no discrepancy the greedy design of six points puts
    five at the two ends after the centre (the variance of the fitted line is smallest there); when the truth may bend
    (a discrepancy of 0.4 rad lengthscale, ten times the noise), the robust design spreads them inside,
    and the criterion's expected error under such a bend is smaller than the ends' design's (the
    criterion itself is checked against simulated calibrations in the Monte-Carlo test above)."""
    x = np.repeat(np.linspace(-1, 1, 41), 6)  # every point may be measured six times
    q = x[:, None]
    x_eval = np.linspace(-1, 1, 101)
    jc, je = line(x) / SIGMA, line(x_eval)
    prior = np.eye(2) * 1e-6
    flat = dd.robust_design(jc, q, je, x_eval[:, None], prior, dd.Discrepancy(np.array([0.4]), 0.0), SIGMA, budget=6)
    assert np.sum(np.abs(x[flat.chosen]) == 1.0) == 5  # greedy: the centre first (one point), then the ends
    bend = dd.Discrepancy(np.array([0.4]), 10 * SIGMA)
    robust = dd.robust_design(jc, q, je, x_eval[:, None], prior, bend, SIGMA, budget=6)
    assert np.sum(np.abs(x[robust.chosen]) == 1.0) <= 1 and np.sum(np.abs(x[robust.chosen]) < 0.8) >= 4
    ends = dd.expected_squared_errors(jc[flat.chosen], q[flat.chosen], prior, je, x_eval[:, None], bend, SIGMA)
    spread = dd.expected_squared_errors(jc[robust.chosen], q[robust.chosen], prior, je, x_eval[:, None], bend, SIGMA)
    # the line fits one axis; the bend on the other two is the same under both designs
    other_axes = 2 * bend.signal_std**2
    assert spread.mean() - other_axes < 0.7 * (ends.mean() - other_axes)


def test_the_default_prior_and_a_campaigns_gp():
    q = np.array([[0.0, 1.0, 0.3], [0.5, -1.0, 0.3]])
    prior = dd.workspace_discrepancy(q, 2e-5)
    np.testing.assert_allclose(prior.lengthscales[:2], [0.5, 2.0])
    assert np.isinf(prior.lengthscales[2]) and prior.signal_std == 2e-5
    with pytest.raises(ValueError, match="signal std"):
        dd.workspace_discrepancy(q, -1.0)
    measured = dd.discrepancy_of({"lengthscales_rad": [0.1, None, 0.3], "signal_std_m": 3e-5, "noise_std_m": 1e-5})
    assert np.isinf(measured.lengthscales[1]) and measured.signal_std == 3e-5
    assert measured.report()["lengthscales_deg"][1] is None


def test_a_campaigns_rows_count_as_chosen_before_the_first_step():
    """Starting from measured rows (their information in the prior, their discrepancy in B, H, U)
    gives the same next choices and expected errors as choosing those rows first."""
    rng = np.random.default_rng(5)
    q_c, q_e, jc, je, prior = toy(rng)
    discrepancy = dd.Discrepancy(np.array([0.7, 1.0, 1.5]), 2 * SIGMA)
    measured = [3, 11, 20]
    campaign = prior + dp.information(jc[measured])
    rest = [c for c in range(len(q_c)) if c not in measured]

    def after_campaign(measured_jacobian, q_measured, budget):
        return dd.robust_design(
            jc[rest], q_c[rest], je, q_e, campaign, discrepancy, SIGMA, budget=budget,
            measured_jacobian=measured_jacobian, q_measured=q_measured,
        )  # fmt: skip

    after = after_campaign(jc[measured], q_c[measured], 4)
    for n in range(5):
        rows = measured + [rest[c] for c in after.chosen[:n]]
        direct = dd.expected_squared_errors(jc[rows], q_c[rows], prior, je, q_e, discrepancy, SIGMA)
        assert after.bounds["expected_rms_mm"].iloc[n] == pytest.approx(np.sqrt(direct.mean() / 3) / 1e-3, rel=1e-6)
    totals = [
        dd.expected_squared_errors(jc[measured + [c]], q_c[measured + [c]], prior, je, q_e, discrepancy, SIGMA).sum()
        for c in rest
    ]
    assert rest[int(np.argmin(totals))] == rest[after.chosen[0]]
    many = dd.MAX_MEASURED_ROWS + 1
    with pytest.raises(ValueError, match="at most 3000"):
        after_campaign(np.repeat(jc[measured[:1]], many, axis=0), np.repeat(q_c[measured[:1]], many, axis=0), 1)


def test_the_command_line_writes_a_robust_design_and_refuses_a_discrepancy_without_it(tmp_path, capsys):
    import pandas as pd

    from remaster import cli

    from .test_design import _robot_arguments

    out = tmp_path / "robust.csv"
    arguments = ["plan", "--objective", "workspace", *_robot_arguments(), "--evaluation", "60", "--candidates", "25"]
    assert cli.main([*arguments, "--criterion", "robust", "--budget", "6", "--out", str(out)]) == 0
    plan, bounds = pd.read_csv(out), pd.read_csv(tmp_path / "robust_bound.csv")
    assert len(plan) == 6 and list(bounds["n"]) == list(range(7))
    np.testing.assert_allclose(plan["expected_rms_mm"], bounds["expected_rms_mm"][1:])
    np.testing.assert_allclose(bounds["gain_mm"][1:], -np.diff(bounds["expected_rms_mm"]))
    assert "signal_std_mm': 0.01" in capsys.readouterr().out  # the default: the sensor's noise (--noise-mm)
    larger = tmp_path / "larger.csv"
    assert (
        cli.main(
            [*arguments, "--criterion", "robust", "--discrepancy-mm", "0.05", "--budget", "6", "--out", str(larger)]
        )
        == 0
    )
    assert pd.read_csv(larger)["expected_rms_mm"].iloc[-1] > plan["expected_rms_mm"].iloc[-1]
    paper = ["plan", *_robot_arguments(), "--criterion", "robust", "--out", str(tmp_path / "paper.csv")]
    assert cli.main(paper) == 2 and not (tmp_path / "paper.csv").exists()
    assert "--criterion: the workspace design's, not the paper planner's" in capsys.readouterr().err
    for refused in (
        ["--discrepancy-mm", "0.05"],
        ["--criterion", "robust", "--discrepancy-mm", "-1"],
        ["--criterion", "robust", "--exchange"],
    ):
        assert cli.main([*arguments, *refused, "--budget", "6", "--out", str(tmp_path / "refused.csv")]) == 2
        assert not (tmp_path / "refused.csv").exists()
    err = capsys.readouterr().err
    assert "--discrepancy-mm" in err and "--exchange" in err


def test_the_documents_show_the_benchmark_as_it_wrote_it():
    """docs/planning.md carries benchmarks/results/robust_planner.md and README.md its UR5 verdict."""
    assert_documents_show("bench_robust_design", "robust_planner")


def test_the_candidates_scored_in_chunks_choose_as_at_once(monkeypatch):
    rng = np.random.default_rng(6)
    q_c, q_e, jc, je, prior = toy(rng)
    discrepancy = dd.Discrepancy(np.array([0.7, 1.0, 1.5]), 2 * SIGMA)
    whole = dd.robust_design(jc, q_c, je, q_e, prior, discrepancy, SIGMA, budget=6)
    monkeypatch.setattr(dd, "SCORE_CHUNK", 3)
    chunked = dd.robust_design(jc, q_c, je, q_e, prior, discrepancy, SIGMA, budget=6)
    np.testing.assert_array_equal(chunked.chosen, whole.chosen)
    np.testing.assert_allclose(chunked.bounds["expected_rms_mm"], whole.bounds["expected_rms_mm"], rtol=1e-12)


def test_a_campaigns_gp_is_the_prior_with_the_joints_it_never_turned_given_the_workspaces_range():
    """--from-results with a residual GP that found structure: its std and lengthscales, except a joint
    the campaign never turned (null), which takes its range over the workspace rather than none (a
    discrepancy constant along the joint the next configurations should move); --discrepancy-mm sets the
    std; without a GP, the default from the sensor's noise."""
    from remaster.planning.plan import PlanOptions, discrepancy_prior

    q_eval = np.array([[0.0, 0.0, -1.0], [1.0, 0.5, 1.0]])
    gp = {"hyperparameters": {"lengthscales_rad": [0.1, 0.3, None], "signal_std_m": 5e-5, "noise_std_m": 2e-5}}
    found = discrepancy_prior(PlanOptions(), q_eval, 3e-5, gp)
    np.testing.assert_allclose(found.lengthscales, [0.1, 0.3, 2.0])
    assert found.signal_std == 5e-5
    assert discrepancy_prior(PlanOptions(discrepancy_mm=0.02), q_eval, 3e-5, gp).signal_std == pytest.approx(2e-5)
    default = discrepancy_prior(PlanOptions(), q_eval, 3e-5, None)
    np.testing.assert_allclose(default.lengthscales, [1.0, 0.5, 2.0])
    assert default.signal_std == 3e-5
