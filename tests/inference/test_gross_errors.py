"""The gross-error rule (`remaster.inference.gross_errors`) and the zero-offset model's screen in the
prepare stage (`fit.screened_rows`): on a campaign whose zero-offset model lacks an effect, the robust
screen flags good rows and the fit's own Beta/F screen restores them; glitches of 2-5 mm injected
by the simulator (rows recorded in its truth) are found; the turns stop at a cycle."""

import numpy as np

from remaster import api
from remaster.campaigns import folders, scenario
from remaster.inference import fit, gross_errors

from ..conftest import REPO
from ..loop.test_gross_errors import COMPLIANCE, _spec


def _campaign(tmp_path, seed: int, truth=None, glitches=None):
    spec = _spec(seed, truth, glitches)
    out = scenario.simulate(spec, folders.read_campaign(REPO / "data" / "raw" / "kuka-compliance", REPO).chain)
    folder = folders.write_campaign(tmp_path / str(seed) / spec["name"], out.metadata, out.tables)
    return folders.read_campaign(folder, REPO), out.truth


def _screened(campaign):
    registration = fit.registration_stage(campaign, "laser_tracker")
    return fit.screened_rows(
        campaign.chain, campaign.sensors["laser_tracker"], registration.t_nr, api.settings()["outliers"]
    )


def test_good_rows_the_robust_screen_flags_where_the_model_lacks_an_effect_are_restored(tmp_path):
    """Compliance the zero-offset model lacks: its residuals are not noise, so the robust scale
    (1.4826 MAD) flags good rows; against the fit's own sum of squares none is beyond the threshold,
    and the paper model is fitted on every row."""
    campaign, _ = _campaign(tmp_path, 1, COMPLIANCE)
    rows, record = _screened(campaign)
    assert len(record["robust_screen"]) > 0  # what the robust scale got wrong
    assert rows.tolist() == [] and record["settled"]
    assert record["rounds"][0]["fitted_without"] == record["robust_screen"]
    assert (
        record["screen"]["rows_tested"] == len(campaign.sensors["laser_tracker"].measured_rows("optimization"))
        and record["screen"]["law"] == gross_errors.STUDENTIZED
    )


def test_glitches_behind_no_model_error_are_found_and_left_out_of_the_paper_fit(tmp_path):
    campaign, truth = _campaign(tmp_path, 3, glitches={"optimization": 3, "validation": 0, "size_mm": [2.0, 5.0]})
    injected = truth["sensors"]["laser_tracker"]["gross_errors"]["rows"]["optimization"]
    rows, record = _screened(campaign)
    assert rows.tolist() == sorted(injected) and record["settled"]
    _, content = fit.prepare_stage(campaign, "laser_tracker", api.settings()["outliers"])
    assert content["excluded_rows_outliers"] == sorted(injected)
    assert content["outlier_screen"]["rounds"][-1]["fitted_without"] == sorted(injected)


def test_the_turns_stop_at_a_cycle_and_the_last_fit_stands():
    finds = {(): [1], (1,): [2], (2,): [1]}
    turns = gross_errors.settle(lambda excluded: (tuple(excluded), np.array(finds[tuple(excluded)])), [])
    assert not turns.settled and turns.fit == (2,) and turns.excluded.tolist() == [2]
    assert [t["found"] for t in turns.history] == [[1], [2], [1]]
    settled = gross_errors.settle(lambda excluded: (None, np.array([4])), [4])
    assert settled.settled and len(settled.history) == 1


def test_an_isolated_row_is_a_gross_error_and_a_shared_or_common_departure_is_not():
    """The rule alone, on distances given: one pose's every configuration beyond the threshold is not
    isolated; more rows beyond it than max_share allows is systematic."""

    def judged(beyond_rows, poses, max_share=0.1):
        n = len(poses)
        distance2 = np.where(np.isin(np.arange(n), beyond_rows), 100.0, 1.0)
        return gross_errors.Screen(
            "validation",
            np.arange(n),
            np.asarray(poses),
            np.zeros(n, bool),
            distance2,
            distance2,
            np.full(n, 20.0),
            0.01,
            max_share,
            1e-5,
            "",
        ).gross.tolist()

    poses = np.repeat(np.arange(10), 2)  # 20 rows, two configurations per pose
    assert judged([3], poses) == [3]
    assert judged([3, 8], poses) == [3, 8]
    assert judged([2, 3], poses) == []  # both configurations of pose 1
    assert judged([1, 3, 5], poses) == []  # 3 > 0.1 x 20: systematic
    assert judged([0], np.arange(5)) == [0]  # a single row is always isolated (max(1, ...))


def test_a_screen_that_cannot_be_fitted_keeps_the_robust_screens_rows_and_says_why(tmp_path, monkeypatch):
    """A full-pose probe of a few rows may be fitted with its orientations and not by its points
    alone: the robust screen's rows stand and the record says why, no traceback."""
    campaign, _ = _campaign(tmp_path, 1, COMPLIANCE)

    def cannot(model):
        raise ValueError("9 residuals cannot determine 12 parameters and sigma (need k > P + 1)")

    monkeypatch.setattr(fit, "laplace_fit", cannot)
    rows, record = _screened(campaign)
    assert rows.tolist() == record["robust_screen"] and len(rows) > 0
    assert record["not_made"].startswith("9 residuals cannot determine") and "rounds" not in record
