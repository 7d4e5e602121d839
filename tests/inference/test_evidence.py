"""Cross-validation folds one weak direction cannot derail (`remaster.inference.evidence`): a fold
whose fit departs is found and decides nothing, and the paired fall is taken per fold on the log
scale, so that one fold can neither veto nor force a candidate."""

import numpy as np
import pytest

from remaster.campaigns import arm_kinds
from remaster.inference import blocks, evidence, fit
from remaster.inference.readings import Readings
from remaster.robot.priors import Priors

from ..conftest import REPO

NOISE = 1.0e-5


def _clustered_campaign(rng):
    """An iiwa's readings: one fold of 10 configurations across the joint space, four folds of 5
    configurations within 1 mrad of one configuration (their marker points lie within a millimetre),
    so that without the first fold the registration's orientation is almost free."""
    spec = arm_kinds.iiwa_scenario("clustered", seed=6)
    chain, sensor = arm_kinds.simulated_sensor(spec, "laser_tracker", REPO)
    registration = fit.register(chain, sensor)
    _, analysis, _ = fit.build_model(chain, sensor, registration.t_nr)
    wide = rng.uniform(-1.0, 1.0, (10, 7)) * np.array([1.5, 1.0, 0.0, 1.2, 1.5, 1.2, 1.5]) + [0, 0, 0, 1.0, 0, 0, 0]
    centre = np.array([0.3, 0.5, 0.0, 1.1, 0.2, -0.4, 0.1])
    cluster = centre + rng.uniform(-1e-3, 1e-3, (20, 7)) * np.array([1, 1, 0, 1, 1, 1, 1])
    q = np.vstack([wide, cluster])
    folds = np.concatenate([np.zeros(10, int), np.repeat(np.arange(1, 5), 5)])
    data = Readings(np.arange(len(q)), q, np.zeros((len(q), 3)))
    model = blocks.BlockModel(chain, data, sensor.marker, registration.t_nr, (), analysis.held)
    truth = model.predict(np.zeros(len(model.names)))
    data = Readings(data.rows, q, truth + rng.normal(0.0, NOISE, truth.shape))
    return blocks.BlockModel(chain, data, sensor.marker, registration.t_nr, (), analysis.held), folds


def test_a_fold_whose_fit_departs_is_found_and_left_out_of_the_rmse():
    """Without the spread fold the clustered folds leave the registration's orientation almost free:
    that fold's held-out RMS is far above what a correct model gives even after its fit is iterated,
    so it is marked departed; the other folds predict at the noise and make the pooled RMSE."""
    model, folds = _clustered_campaign(np.random.default_rng(3))
    mode = evidence.posterior_mode(model)
    cv = evidence.cross_validate(mode, folds)
    assert cv.departed.tolist() == [True, False, False, False, False]
    assert np.sqrt(cv.mse[0] / 3.0) > 100 * NOISE
    assert cv.rmse / np.sqrt(3.0) < 3.0 * NOISE


def _with_link_geometry(model, scale: float):
    """The model with the link geometry block under the configured industrial priors times scale."""
    values = {"link_translation_mm": 1.0 * scale, "link_rotation_deg": 0.1 * scale}
    priors = Priors("industrial", values)
    return blocks.BlockModel(model.chain, model.data, model.marker, model.t_nr, ("link_geometry",), model.fixed, priors)


def test_no_fold_moves_a_parameter_beyond_its_prior_range_unreported():
    """Every fold of the clustered design, with the link geometry under its priors (at 0.01, 1 and
    100 times their size): a fold whose fit moves a link parameter beyond PRIOR_RANGE prior standard
    deviations from the full fit is departed; the departed spread fold's move is recorded too."""
    for scale in (0.01, 1.0, 100.0):
        model, folds = _clustered_campaign(np.random.default_rng(3))
        cv = evidence.cross_validate(evidence.posterior_mode(_with_link_geometry(model, scale)), folds)
        assert len(cv.prior_steps) == 5 and np.all(cv.prior_steps > 0)
        assert not np.any((cv.prior_steps > evidence.PRIOR_RANGE) & ~cv.departed)
        assert cv.departed[0]


def test_a_fold_moving_a_parameter_beyond_its_prior_range_departs(monkeypatch):
    """The prior-range test alone departs a fold: with the range narrowed below the moves the
    clustered folds make (a few hundredths of a prior sd at 0.01 x the priors), the folds whose
    held-out error is at the noise are departed by their move, which the held-out test does not see."""
    model, folds = _clustered_campaign(np.random.default_rng(3))
    mode = evidence.posterior_mode(_with_link_geometry(model, 0.01))
    wide = evidence.cross_validate(mode, folds)
    assert wide.departed.tolist() == [True, False, False, False, False]
    monkeypatch.setattr(evidence, "PRIOR_RANGE", float(np.median(wide.prior_steps[1:])))
    narrow = evidence.cross_validate(mode, folds)
    assert np.all(narrow.mse[1:] < 3.0 * (evidence.DEPARTED_RATIO * mode.sigma) ** 2)  # not by their error
    moved = narrow.prior_steps > evidence.PRIOR_RANGE
    assert moved[1:].any() and not moved[1:].all()
    assert narrow.departed.tolist() == [True] + moved[1:].tolist()


def _cv(mse, departed=None):
    return evidence.CrossValidation(np.asarray(mse, float), np.full(len(mse), 10), departed=departed)


def test_one_fold_can_neither_veto_nor_force_a_candidate():
    """On the log scale a candidate removing 90-99 % of the error in every fold passes however
    unequal the folds' errors (on differences of mean squares one fold's larger error made the
    spread); a single fold's enormous fall cannot make a candidate that does nothing elsewhere pass;
    a departed fold is left out of the statistic, its K and the per-fold falls."""
    before = _cv([1.0, 1.2, 0.9, 1.1, 60.0])
    after = _cv([0.05, 0.08, 0.02, 0.1, 0.6])
    gain = evidence.cv_gain(before, after)
    assert gain["cv_mse_fall_in_se"] > 5.0
    assert gain["cv_mse_fall_mm2"] / gain["cv_mse_fall_se_mm2"] < 2.87  # what the old statistic saw
    assert gain["cv_fold_falls"] == pytest.approx([0.95, 1 - 0.08 / 1.2, 1 - 0.02 / 0.9, 1 - 0.1 / 1.1, 0.99])
    forced = evidence.cv_gain(_cv([1.0, 1.0, 1.0, 1.0, 60.0]), _cv([1.02, 0.99, 1.01, 1.0, 0.6]))
    assert forced["cv_mse_fall_in_se"] < 2.0
    departed = np.array([False, False, False, False, True])
    left_out = evidence.cv_gain(_cv([1.0, 1.2, 0.9, 1.1, 60.0], departed), after)
    assert left_out["cv_departed_folds"] == [4] and left_out["cv_folds"] == 4
    one_left = evidence.cv_gain(_cv([1.0, 60.0], [False, True]), _cv([0.5, 0.6]))
    assert one_left["cv_mse_fall_in_se"] == -np.inf  # no decision on one fold


def test_a_jackknife_group_whose_refit_departs_is_left_out_of_u_between_and_named():
    """The clustered design as jackknife groups (each fold one pose, measured in turn, so the groups
    contiguous in time are the folds: the spread configurations group 0): without them the
    registration's orientation is almost free, the refit departs on them, and its estimate, which
    measures that freedom rather than the design, is left out; the four others give u_between, and
    the loop's warning names the group."""
    from remaster.loop import jackknife
    from remaster.loop.fitted import Fitted

    model, folds = _clustered_campaign(np.random.default_rng(3))
    mode = evidence.posterior_mode(model)
    poses = folds
    assert (evidence.time_folds(np.arange(len(poses)), poses, 5) == folds).all()  # the row order as time
    fitted = Fitted(mode, None, evidence.cross_validate(mode, folds))
    result = jackknife.zero_offset_jackknife(fitted, poses, 5)
    assert result["departed_groups"] == [0] and result["groups"] == 4
    assert all(len(p["estimates_deg"]) == 4 for p in result["parameters"].values())
    warning = jackknife.departed_groups_warning({"paper": result})
    assert warning.startswith("jackknife groups whose refit departed") and "paper: group 0;" in warning


# --------------------------------------------------------------------------- held-out regions


def _blobs(rng, centres, per=6, spread=0.3):
    """Points (m, d) in blobs about centres (k, d), per points each, labelled by blob (m,)."""
    centres = np.asarray(centres, dtype=float)
    points = np.concatenate([c + rng.normal(0.0, spread, (per, centres.shape[1])) for c in centres])
    return points, np.repeat(np.arange(len(centres)), per)


def test_region_folds_are_deterministic_cover_every_row_and_keep_poses_whole(rng):
    """Three rows per pose, features a pose's rows share up to noise: every row in a fold, K folds,
    no pose split, the same folds on a second call (the seeded starts), others for another seed only
    by their numbering at most (the regions are the blobs)."""
    points, blob = _blobs(rng, [[0, 0], [6, 0], [0, 6], [6, 6], [20, 20]])
    poses = np.repeat(np.arange(len(points)), 3)
    features = np.repeat(points, 3, axis=0) + rng.normal(0.0, 0.01, (3 * len(points), 2))
    folds, centres = evidence.region_folds(features, poses, 5)
    assert folds.shape == poses.shape and set(folds) == set(range(5)) and centres.shape == (5, 2)
    assert all(len(set(folds[poses == p])) == 1 for p in np.unique(poses))
    assert np.array_equal(folds, evidence.region_folds(features, poses, 5)[0])
    by_pose = folds[::3]
    assert all(len(set(by_pose[blob == b])) == 1 for b in range(5))  # a blob is one region
    assert len({tuple(sorted(set(by_pose[blob == b]))) for b in range(5)}) == 5
    with pytest.raises(ValueError, match="4 poses cannot make 5 regions"):
        evidence.region_folds(features[:12], poses[:12], 5)


def test_regions_are_contiguous_voronoi_cells(rng):
    """Points spread evenly (no blobs to find): each point is nearer the centre of its own region
    than any other's, so no region has a hole another region's point sits in; numbered by first pose."""
    points = rng.uniform(-1.0, 1.0, (60, 3))
    folds, centres = evidence.region_folds(points, np.arange(60), 5, seed=3)
    nearest = np.argmin(np.sum((points[:, None, :] - centres[None]) ** 2, axis=-1), axis=1)
    assert np.array_equal(nearest, folds)
    firsts = [np.flatnonzero(folds == k)[0] for k in range(5)]
    assert firsts == sorted(firsts)
