"""The workspace design (remaster.planning.design*): the rank-3 updates against the direct inverse, the
95 % bound against closed forms, the greedy design's bound against n, D-optimality, bad candidate
tables, the command line, and a planned design against random ones of the same size."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from remaster import cli
from remaster.campaigns.arm_kinds import IIWA, TRACKER, chain_of, iiwa_scenario, joint_never_moved, simulated_sensor
from remaster.errors import InputError
from remaster.inference.bounds import bound_from_covariances
from remaster.planning import design, plan_inputs
from remaster.planning import design_posterior as dp
from remaster.robot.priors import priors_from, with_defaults

from ..conftest import REPO, assert_documents_show

ORIGIN = np.array(TRACKER["position"])
MARKER = np.array(TRACKER["marker"])


@pytest.fixture(scope="module")
def iiwa():
    """(chain, error model, candidates table, candidate Jacobian, evaluation Jacobian) of a small design."""
    chain = chain_of(iiwa_scenario("design"), REPO)
    t_nr = np.eye(4)
    t_nr[:3, 3] = -ORIGIN
    model = dp.complete_error_model(chain, MARKER, t_nr, priors_from(with_defaults(None)), TRACKER["noise"])
    rng = np.random.default_rng(3)
    candidates = plan_inputs.generated_candidates(chain, ORIGIN, MARKER, rng, poses=40)
    q = plan_inputs.configurations(candidates, chain.n_joints)
    evaluation = design.evaluation_configurations(chain, 120, rng)
    return chain, model, candidates, model.whitened_jacobian(q), model.jacobian(evaluation)


def _random_problem(seed=0, p=6, k=4, e=5):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(p, p))
    prior = a @ a.T + p * np.eye(p)
    return prior, rng.normal(size=(k, 3, p)), rng.normal(size=(e, 3, p))


def test_rank_three_updates_equal_the_direct_inverse():
    prior, jacobians, _ = _random_problem()
    sigma = np.linalg.inv(prior)
    for j in jacobians:
        sigma = dp.woodbury_update(sigma, j)
    direct = np.linalg.inv(prior + sum(j.T @ j for j in jacobians))
    np.testing.assert_allclose(sigma, direct, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(dp.covariance(prior + dp.information(jacobians)), direct, rtol=1e-10, atol=1e-12)


def test_candidate_scores_equal_the_objective_after_a_direct_inverse():
    prior, candidates, evaluation = _random_problem(seed=1, k=6, e=40)
    sigma = np.linalg.inv(prior)
    for statistic in design.STATISTICS:
        scored = design.candidate_objectives(sigma, candidates, evaluation, statistic)
        for c, j in enumerate(candidates):
            after = np.linalg.inv(prior + j.T @ j)
            bounds = bound_from_covariances(np.einsum("eip,pq,ejq->eij", evaluation, after, evaluation))
            expected = np.quantile(bounds, 0.95) if statistic == "p95" else np.mean(bounds)
            assert scored[c] == pytest.approx(expected, rel=1e-9)
    gains = design.log_det_gains(sigma, candidates)
    for c, j in enumerate(candidates):
        expected = np.linalg.slogdet(prior + j.T @ j)[1] - np.linalg.slogdet(prior)[1]
        assert gains[c] == pytest.approx(expected, rel=1e-9)


def test_the_greedy_bound_never_rises_and_stops_at_its_target(iiwa, caplog):
    _, model, _, candidates, evaluation = iiwa
    with caplog.at_level("INFO", logger="remaster.planning.design"):
        greedy = design.greedy_design(candidates, evaluation, model.prior_information(), budget=25)
    p95 = greedy.bounds["bound_p95_mm"].to_numpy()
    assert len(greedy.chosen) == 25 and len(set(greedy.chosen)) == 25
    told = [r.getMessage() for r in caplog.records]  # each choice, for a terminal's progress
    assert len(told) == 25 and told[-1] == f"25 of at most 25 configurations chosen, p95 bound {p95[-1]:.4g} mm"
    assert np.all(np.diff(p95) <= 1e-12 * p95[:-1])
    assert np.all(np.diff(greedy.bounds["log_det_information"]) > 0)
    # a target between two rows of the budget run stops at the first row at or below it (same steps)
    target = 0.5 * (p95[15] + p95[16]) * 1e-3
    stopped = design.greedy_design(candidates, evaluation, model.prior_information(), target=target)
    assert stopped.stopped == "target" and len(stopped.chosen) == 16
    np.testing.assert_array_equal(stopped.chosen, greedy.chosen[:16])


def test_d_optimal_picks_the_largest_log_det_each_step(iiwa):
    _, model, _, candidates, evaluation = iiwa
    d_opt = design.greedy_design(candidates, evaluation, model.prior_information(), budget=3, criterion="d-optimal")
    information = model.prior_information()
    for pick in d_opt.chosen:
        every = [np.linalg.slogdet(information + j.T @ j)[1] for j in candidates]
        assert every[pick] == pytest.approx(max(every), abs=1e-6)
        information = information + candidates[pick].T @ candidates[pick]
    with pytest.raises(ValueError, match="criterion"):
        design.greedy_design(candidates, evaluation, model.prior_information(), budget=1, criterion="a-optimal")


def test_a_planned_design_predicts_a_smaller_bound_than_random_ones(iiwa):
    chain, model, _, candidates, evaluation = iiwa
    n = 15
    planned = design.greedy_design(candidates, evaluation, model.prior_information(), budget=n)
    # judged at other workspace configurations than those it was chosen for
    judge = model.jacobian(design.evaluation_configurations(chain, 200, np.random.default_rng(11)))

    def bound(chosen):
        return design._summary(model.prior_information() + dp.information(candidates[chosen]), judge)[0]

    rng = np.random.default_rng(12)
    random = [bound(rng.choice(len(candidates), n, replace=False)) for _ in range(7)]
    assert bound(planned.chosen) < min(random)


def test_a_campaign_that_never_moved_joint_3_shows_it_and_informs_the_next_design():
    chain, sensor = simulated_sensor(joint_never_moved(), "laser_tracker", REPO)
    t_nr = np.eye(4)
    t_nr[:3, 3] = -ORIGIN
    priors = priors_from(with_defaults(None))
    start = plan_inputs.campaign_prior(chain, sensor, t_nr, TRACKER["noise"], priors)
    assert start.moved_fraction[2] == 0.0 and np.all(np.delete(start.moved_fraction, 2) > 0.1)
    assert len(start.rows) == len(sensor.measured_rows("optimization"))
    q = design.evaluation_configurations(chain, 80, np.random.default_rng(5))
    evaluation = start.model.jacobian(q)
    alone = design._summary(start.model.prior_information(), evaluation)[0]
    with_campaign = design._summary(start.information, evaluation)[0]
    assert with_campaign < 1e-3 * alone  # 25 configurations determine what the prior alone does not


def _table(rows):
    return pd.DataFrame(rows, columns=[f"q{j + 1}" for j in range(7)])


def test_bad_candidate_tables_name_the_file_column_and_rows():
    chain = chain_of(iiwa_scenario("design"), REPO)
    good = [[0.1] * 7, [0.2] * 7]
    with pytest.raises(InputError, match=r"c\.csv: q7: missing") as missing:
        plan_inputs.table_candidates(_table(good).drop(columns="q7"), chain, "c.csv")
    assert missing.value.key == "q7"
    bad = _table(good + [[0.1] * 6 + ["x"]])
    with pytest.raises(InputError) as text:
        plan_inputs.table_candidates(bad, chain, "c.csv")
    assert text.value.file == "c.csv" and text.value.rows == [2]
    far = _table(good + [[0.1, 4.0, 0.1, 0.1, 0.1, 0.1, 0.1]])
    with pytest.raises(InputError, match="joint limits") as limits:
        plan_inputs.table_candidates(far, chain, "c.csv")
    assert limits.value.key == "q2" and limits.value.rows == [2]
    with pytest.raises(InputError, match="no rows"):
        plan_inputs.table_candidates(_table([]), chain, "c.csv")
    table = plan_inputs.table_candidates(_table(good), chain, "c.csv")
    assert list(table.columns[:3]) == ["set", "pose", "solution"] and list(table["pose"]) == [0, 1]


def _robot_arguments():
    return [
        "--urdf",
        str(REPO / IIWA["urdf"]),
        "--base",
        IIWA["base"],
        "--flange",
        IIWA["flange"],
        "--sensor-origin",
        *map(str, ORIGIN),
        "--marker",
        *map(str, MARKER),
        "--config",
        str(REPO / "config.yaml"),
    ]


def test_the_command_line_writes_the_design_its_bound_and_figure(tmp_path):
    out = tmp_path / "plan.csv"
    arguments = ["plan", "--objective", "workspace", *_robot_arguments(), "--evaluation", "60"]
    assert cli.main([*arguments, "--candidates", "25", "--budget", "6", "--out", str(out)]) == 0
    plan = pd.read_csv(out)
    bounds = pd.read_csv(tmp_path / "plan_bound.csv")
    assert (tmp_path / "plan_bound.png").is_file() and (tmp_path / "plan_bound.pdf").is_file()
    assert len(plan) == 6 and list(plan["rank"]) == list(range(1, 7))
    assert {"set", "pose", "solution", "q1", "q7", "q1_deg", "q7_deg"} <= set(plan.columns)
    assert list(bounds["n"]) == list(range(7))
    np.testing.assert_allclose(plan["bound_p95_mm"], bounds["bound_p95_mm"][1:])
    # the design it wrote is read back as candidates; a bad one ends with status 2 and names the file
    again = tmp_path / "again.csv"
    assert cli.main([*arguments, "--candidates", str(out), "--budget", "3", "--out", str(again)]) == 0
    assert set(map(tuple, pd.read_csv(again)[["q1", "q2"]].to_numpy())) <= set(
        map(tuple, plan[["q1", "q2"]].to_numpy())
    )
    broken = tmp_path / "broken.csv"
    plan.drop(columns="q4").to_csv(broken, index=False)
    assert cli.main([*arguments, "--candidates", str(broken), "--budget", "3", "--out", str(again)]) == 2
    assert cli.main([*arguments, "--candidates", "25", "--out", str(again)]) == 2  # neither budget nor target
    # the exchange keeps the number and does not raise the final bound; it refuses the d-optimal criterion
    exchanged = tmp_path / "exchanged.csv"
    assert cli.main([*arguments, "--candidates", "25", "--budget", "6", "--exchange", "--out", str(exchanged)]) == 0
    after = pd.read_csv(exchanged)
    assert len(after) == 6 and after["bound_p95_mm"].iloc[-1] <= plan["bound_p95_mm"].iloc[-1] * (1 + 1e-9)
    refused = [*arguments, "--candidates", "25", "--budget", "6", "--exchange", "--criterion", "d-optimal"]
    assert cli.main([*refused, "--out", str(tmp_path / "refused.csv")]) == 2
    assert not (tmp_path / "refused.csv").exists()


def test_the_documents_show_the_benchmark_as_it_wrote_it():
    """docs/planning.md carries benchmarks/results/planner.md and README.md its verdicts."""
    assert_documents_show("bench_planner", "planner")


def test_from_results_without_the_workflows_files_names_the_missing_file(tmp_path, capsys):
    folder = tmp_path / "kuka-twin" / "laser_tracker"
    folder.mkdir(parents=True)
    arguments = ["plan", "--from-results", str(folder), "--campaign", str(REPO / "data" / "raw" / "kuka-twin")]
    assert cli.main([*arguments, "--budget", "2", "--out", str(tmp_path / "next.csv")]) == 2
    assert "registration.json: not written" in capsys.readouterr().err
    wrong = tmp_path / "kuka-twin" / "no_such_sensor"
    wrong.mkdir()
    arguments[2] = str(wrong)
    assert cli.main([*arguments, "--budget", "2", "--out", str(tmp_path / "next.csv")]) == 2
    assert "names no sensor" in capsys.readouterr().err


def test_the_exchange_lowers_the_objective_to_a_point_no_single_swap_improves():
    """Exchange after greedy (known answer by brute force over every single swap of a small problem):
    the final objective is at most the greedy one, the number of configurations stays, and no swap of
    one chosen configuration for one candidate lowers it further."""
    rng = np.random.default_rng(7)
    p, c, e = 5, 14, 30
    candidates = rng.normal(size=(c, 3, p))
    evaluation = rng.normal(size=(e, 3, p)) * 1e-3
    prior = np.eye(p) * 1e-2
    greedy = design.greedy_design(candidates, evaluation, prior, budget=3)
    exchanged = design.exchange_design(greedy, candidates, evaluation, prior)
    assert len(exchanged.chosen) == 3 and len(set(exchanged.chosen)) == 3
    assert exchanged.final_bound_mm <= greedy.final_bound_mm * (1 + 1e-9)
    assert exchanged.stopped.endswith("then exchange")

    def objective(chosen):
        info = prior + dp.information(candidates[list(chosen)])
        return design._summary(info, evaluation)[0]

    final = objective(exchanged.chosen)
    assert final / 1e-3 == pytest.approx(exchanged.final_bound_mm, rel=1e-9)
    for k in range(3):
        for other in set(range(c)) - set(exchanged.chosen):
            swapped = list(exchanged.chosen)
            swapped[k] = other
            assert objective(swapped) >= final * (1 - 1e-6)
    with pytest.raises(ValueError, match="workspace criterion"):
        design.exchange_design(
            design.greedy_design(candidates, evaluation, prior, budget=3, criterion="d-optimal"),
            candidates,
            evaluation,
            prior,
        )


def test_a_campaign_in_the_robots_frame_must_say_where_its_sensor_stood():
    """The published UR5 campaign's coordinates are the robot's (its registration is about the identity):
    generated candidates would be checked against a sight line from the robot's base, from where none of
    its rows is seen, so the command asks for --sensor-origin (or --candidates) instead of failing to find
    candidates; a given origin or a candidates file is taken as it is."""
    from remaster.campaigns import folders
    from remaster.inference import fit
    from remaster.planning.plan import PlanOptions, campaign_sensor_origin

    campaign = folders.read_campaign(REPO / "data" / "raw" / "jacobi-ur5-gts3800", repo_root=REPO)
    chain, sensor = campaign.chain, campaign.sensors["laser_tracker"]
    rows = sensor.measured_rows("optimization")[:50]
    measured = sensor.table.loc[rows, list(sensor.joint_columns)].to_numpy(dtype=float)
    t_nr = fit.register(chain, sensor).t_nr
    args = PlanOptions(candidates="60", link_radius=0.06, floor=0.0)
    with pytest.raises(InputError, match="none of the campaign's 50 measured rows would be seen") as raised:
        campaign_sensor_origin(args, chain, t_nr, sensor, measured)
    assert raised.value.key == "--sensor-origin"
    given = PlanOptions(candidates="60", sensor_origin=(2.0, 0.0, 0.5))
    np.testing.assert_allclose(campaign_sensor_origin(given, chain, t_nr, sensor, measured), [2.0, 0.0, 0.5])
    listed = PlanOptions(candidates="rows.csv")
    np.testing.assert_allclose(
        campaign_sensor_origin(listed, chain, t_nr, sensor, measured), np.linalg.inv(t_nr)[:3, 3]
    )
