"""Sampling coordinates with the exact symmetries folded out: each fold moves no predicted point,
the map is a bijection with the stated Jacobian, a posterior that is Gaussian in the folded
coordinates (a curved ridge in the model's own) is sampled right, and the loop closure's refit
on the bundled twin meets the convergence criteria in its first run."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from remaster.campaigns import folders
from remaster.inference.extensions import extended_model
from remaster.inference.gauge import MARKER, FoldedTarget, Gauge, MarkerTurn, last_axis, sampling_coordinates
from remaster.inference.posterior_sampling import sampler_diagnostics
from remaster.inference.readings import readings
from remaster.inference.sampling.chains import run_chains
from remaster.inference.sampling.independence import metropolis_independence
from remaster.inference.sampling.target import CallableTarget
from remaster.robot.kinematics import marker_positions
from remaster.robot.priors import priors_from, with_defaults

from ..conftest import REPO

SIR = np.array([0.1, 0.0, 0.02])  # the twin's motion-capture marker, 100 mm off the flange axis


def turn_of(chain, marker=SIR, index=(0, 1, 2)) -> MarkerTurn:
    return MarkerTurn.about(np.array(index), marker, *last_axis(chain))


@pytest.mark.parametrize("robot", ["iiwa", "ur5_dh"])
def test_a_tangential_shift_is_a_turn_of_the_last_joint(robot, request, rng):
    chain = request.getfixturevalue(robot)
    turn = turn_of(chain)
    q = rng.uniform(-2.0, 2.0, (20, chain.n_joints))
    angle, radial, axial = 0.01, 3e-4, -2e-4
    moved, _ = turn.unfold(np.array([0.0, turn.radius * angle, 0.0]))
    turned = q.copy()
    turned[:, -1] += angle
    np.testing.assert_allclose(
        marker_positions(chain, q, turn.marker + moved), marker_positions(chain, turned, turn.marker), atol=1e-12
    )
    shifted, _ = turn.unfold(np.array([radial, 0.0, axial]))  # the others: along the radius and the axis
    np.testing.assert_allclose(shifted, radial * turn.radial + axial * turn.axis, atol=1e-15)


@pytest.fixture(scope="module")
def twin_model(iiwa):
    """The twin's laser-tracker optimization rows under every block the folds concern, the
    link-geometry parameters absorbed at every configuration held (as the loop holds them)."""
    campaign = folders.read_campaign(REPO / "data" / "raw" / "kuka-twin", repo_root=REPO)
    sensor = campaign.sensors["laser_tracker"]
    data = readings(campaign.chain, sensor, "optimization")
    model, _ = extended_model(
        campaign.chain,
        data,
        sensor.marker,
        np.eye(4),
        ("link_geometry", "marker_offset"),
        {"zero_offsets.q1": 0.0},
        priors_from(with_defaults(None)),
    )
    names = model.names + ("noise.sigma",)
    gauge = Gauge.of(names, model.chain, model.marker, model.t_nr, np.diag(np.full(len(names), 1e-3**2)))
    return model, names, gauge


def test_each_fold_moves_no_predicted_point(twin_model, rng):
    """Moving a folded-out parameter (the marker's turn against joint 7) with the folded
    coordinates kept changes no prediction; in the model's own parameters the marker and joint 7
    move to make up for it."""
    model, names, gauge = twin_model
    assert [type(f).__name__ for f in gauge.folds] == ["MarkerTurn"]
    theta = np.append(rng.normal(0.0, 1e-3, len(model.names)), 1e-5)
    folded = gauge.fold(theta)
    before = model.predict(theta[:-1])
    turn = gauge.folds[0]
    for moves in ({"marker_offset.y": 1e-3, "zero_offsets.q7": -1e-3 / turn.radius},):
        moved = folded.copy()
        for name, step in moves.items():
            moved[names.index(name)] += step
        after, _ = gauge.unfold(moved)
        np.testing.assert_allclose(model.predict(after[:-1]), before, atol=1e-14)
        assert np.abs(after - theta).max() > 1e-4  # the model's parameters did move


def test_the_map_is_a_bijection_with_its_jacobian(twin_model, rng):
    model, names, gauge = twin_model
    theta = np.append(rng.normal(0.0, 1e-3, (30, len(model.names))), np.full((30, 1), 1e-5), axis=1)
    back, _ = gauge.unfold(gauge.fold(theta))
    np.testing.assert_allclose(back, theta, atol=1e-13)
    point, step = gauge.fold(theta[0]), 1e-7
    steps = np.eye(len(point)) * step
    numeric = ((gauge.unfold(point + steps)[0] - gauge.unfold(point - steps)[0]) / (2 * step)).T
    assert gauge.unfold(point)[1] == pytest.approx(np.linalg.slogdet(numeric)[1], abs=1e-6)


def test_it_folds_only_what_applies(iiwa):
    covariance = np.diag(np.full(4, 1e-3**2))
    names = MARKER + ("noise.sigma",)
    assert [type(f).__name__ for f in Gauge.of(names, iiwa, SIR, np.eye(4), covariance).folds] == ["MarkerTurn"]
    assert (
        Gauge.of(
            ("marker_offset.x", "marker_offset.z", "zero_offsets.q7", "noise.sigma"), iiwa, SIR, np.eye(4), covariance
        )
        is None
    )  # y held: nothing to fold
    centre, axis = last_axis(iiwa)
    assert (
        Gauge.of(names, iiwa, centre + 0.05 * axis + [3e-3, 0, 0], np.eye(4), covariance) is None
    )  # 3 mm off, spread 1 mm


def test_a_ridge_curved_in_xyz_is_sampled_right_in_the_folded_coordinates(iiwa):
    """Known answer: a posterior Gaussian in (radial, tangential, axial, sigma) is a banana in
    x, y, z (tangential spread 10 mm at a radius of 100 mm, the others 0.02 mm). Independence
    Metropolis from its Laplace approximation in the folded coordinates reproduces its means and
    standard deviations and passes a KS test on the tangential marginal; from the same Laplace
    approximation in x, y, z it misses the ridge."""
    names = MARKER + ("noise.sigma",)
    mean = np.array([0.0, 0.0, 0.0, 1e-5])
    std = np.array([2e-5, 1e-2, 2e-5, 1e-6])
    gauge = Gauge.of(names, iiwa, SIR, np.eye(4), np.diag(std**2))

    def log_prob_xyz(theta):  # the banana, written in the model's own x, y, z
        folded = gauge.fold(theta)
        return -0.5 * np.sum(((folded - mean) / std) ** 2, axis=-1) - gauge.unfold(folded)[1]

    target = CallableTarget(names, np.full(4, 1e-3), log_prob_xyz)
    laplace_mean = gauge.unfold(mean)[0]
    steps = np.eye(4) * 1e-9
    jacobian = ((gauge.unfold(mean + steps)[0] - gauge.unfold(mean - steps)[0]) / 2e-9).T
    covariance = jacobian @ np.diag(std**2) @ jacobian.T
    start, folded_covariance = gauge.laplace(laplace_mean, covariance, target.scale)
    np.testing.assert_allclose(folded_covariance, np.diag(std**2), rtol=1e-5, atol=1e-20)
    chains = run_chains(
        metropolis_independence,
        FoldedTarget(target, gauge),
        np.random.default_rng(5),
        2,
        start,
        mean=start,
        covariance=folded_covariance,
        n_samples=6000,
        burn_in=1000,
    )
    back = [gauge.back(c) for c in chains]
    report = sampler_diagnostics(back, 1.0)
    assert report["max_rhat"] <= 1.05 and report["min_ess"] >= 200
    draws = gauge.fold(np.concatenate([c.samples for c in back]))
    assert np.all(np.abs(draws.mean(axis=0) - mean) < 4 * std / np.sqrt(report["min_ess"]))
    np.testing.assert_allclose(draws.std(axis=0), std, rtol=0.1)
    assert stats.kstest(draws[::10, 1], stats.norm(0.0, std[1]).cdf).pvalue > 0.01
    np.testing.assert_allclose(back[0].log_prob, log_prob_xyz(back[0].samples), atol=1e-9)
    xyz = np.concatenate([c.samples for c in back])  # on the arc about the axis, 10 mm either side
    turn = gauge.folds[0]
    relative = SIR + xyz[:, :3] - turn.centre
    in_plane = relative - np.outer(relative @ turn.axis, turn.axis)
    np.testing.assert_allclose(np.linalg.norm(in_plane, axis=1), turn.radius, atol=5 * std[0])
    assert np.ptp(relative @ turn.tangential) > 0.03
    plain = run_chains(
        metropolis_independence,
        target,
        np.random.default_rng(5),
        2,
        laplace_mean,
        mean=laplace_mean,
        covariance=covariance,
        n_samples=6000,
        burn_in=1000,
    )
    assert sampler_diagnostics(plain, 1.0)["min_ess"] < report["min_ess"] / 4


def test_the_coordinates_are_those_the_laplace_approximation_fits_best(iiwa):
    """The same marker spread, Gaussian either in cylindrical coordinates (a tool that turns: the
    marker trades with joint 7) or in x, y, z (a tool that never turns: it trades with the
    registration's translation): each is sampled in its own coordinates."""
    names = MARKER + ("noise.sigma",)
    std = np.array([2e-5, 1e-2, 2e-5, 1e-6])
    mean = np.array([0.0, 0.0, 0.0, 1e-5])
    model = SimpleNamespace(chain=iiwa, marker=SIR, t_nr=np.eye(4))
    turned = Gauge.of(names, iiwa, SIR, np.eye(4), np.diag(std**2))

    def in_turned(theta):  # Gaussian in the cylindrical coordinates
        folded = turned.fold(theta)
        return -0.5 * np.sum(((folded - mean) / std) ** 2, axis=-1) - turned.unfold(folded)[1]

    def in_xyz(theta):  # Gaussian in x, y, z
        return -0.5 * np.sum(((np.asarray(theta) - mean) / std) ** 2, axis=-1)

    start = turned.unfold(mean)[0]
    steps = np.eye(4) * 1e-9
    jacobian = ((turned.unfold(mean + steps)[0] - turned.unfold(mean - steps)[0]) / 2e-9).T
    for log_prob, centre, covariance, expected in (
        (in_turned, start, jacobian @ np.diag(std**2) @ jacobian.T, "folded"),
        (in_xyz, mean, np.diag(std**2), "model parameters"),
    ):
        target = CallableTarget(names, np.full(4, 1e-3), log_prob)
        *_, gauge, report = sampling_coordinates(target, model, centre, covariance, np.random.default_rng(2))
        assert report["chosen"] == expected, report
        assert report["laplace_log_weight_std"][expected] < 0.1  # exactly Gaussian there
        assert (gauge is None) == (expected == "model parameters")
