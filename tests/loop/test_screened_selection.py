"""The screen's rounds (`select_screened`) with the fitting replaced by stand-ins, so that the rule
itself is what is tested: the rows reported as flagged are the rows the final model was fitted
without, whether the screen settles or runs out of refits."""

from __future__ import annotations

import types

import numpy as np
import pandas as pd
import pytest

from remaster.inference import gross_errors
from remaster.loop import screened_selection


class _Readings:
    def __init__(self, rows):
        self.rows = np.asarray(rows, dtype=int)
        self.measured = np.zeros((len(self.rows), 3))


@pytest.fixture
def stand_ins(monkeypatch):
    """A six-row optimization set and a two-row validation set; each fit records the rows it was
    fitted without, and its screen finds what `finds(fit)` says (fit: the fit's index)."""
    table = {"optimization": np.arange(6), "validation": np.arange(6, 8)}
    fits: list[list[int]] = []

    def readings(chain, sensor, set_name, model, exclude=()):
        return _Readings([r for r in table[set_name] if r not in set(np.asarray(exclude).tolist())])

    def select(chain, fitted, marker, t_nr, base_held, poses, settings, tracker):
        fits.append([r for r in table["optimization"] if r not in set(fitted.rows.tolist())])
        # a selection that adds an effect on every other fit: each round records what its selection added
        return types.SimpleNamespace(fit=len(fits) - 1, added=("link_geometry",) * (len(fits) % 2))

    def screen(selection, fitted, every, every_poses, set_name, settings):
        rows = stand_ins.finds(selection.fit) if set_name == "optimization" else []
        return types.SimpleNamespace(gross=np.asarray(rows, dtype=int), systematic=False)

    monkeypatch.setattr(screened_selection, "readings", readings)
    monkeypatch.setattr(screened_selection, "select", select)
    monkeypatch.setattr(screened_selection, "_screen", screen)
    monkeypatch.setattr(screened_selection.noise, "frame_problem", lambda t_nr, measured: None)
    monkeypatch.setattr(screened_selection, "fitted_rows", lambda data, poses, limit: (data, poses, {}))
    stand_ins = types.SimpleNamespace(fits=fits, finds=None)
    return stand_ins


def _run():
    sensor = types.SimpleNamespace(
        kind="motion_capture",
        marker=None,
        table=pd.DataFrame({"pose": np.arange(8)}),
    )
    settings = types.SimpleNamespace(model=None, tracker_noise=None, fit_rows=100)
    return screened_selection.select_screened(None, sensor, None, None, settings, exclude=[0])


def test_a_screen_that_settles_flags_the_rows_its_model_was_fitted_without(stand_ins):
    stand_ins.finds = lambda fit: [1]
    screened = _run()
    assert screened.settled and stand_ins.fits == [[0], [1]]
    assert screened.flagged["optimization"].tolist() == [1] == stand_ins.fits[-1]
    assert screened.data["optimization"].rows.tolist() == [0, 2, 3, 4, 5]
    assert screened.provisional.tolist() == [0]
    assert [round_["found"] for round_ in screened.history] == [[1], [1]]
    assert [round_["added"] for round_ in screened.history] == [["link_geometry"], []]


def test_a_screen_out_of_refits_flags_what_its_final_model_was_fitted_without(stand_ins):
    """Each fit finds a new row: after the last refit the rows found are not the ones fitted
    without, and no fit is left to refit without them. The rows reported (and the readings the
    accuracy is taken on) are the final model's, and the warning names both lists apart."""
    stand_ins.finds = lambda fit: [fit + 1]
    screened = _run()
    assert len(stand_ins.fits) == gross_errors.MAX_ROUNDS and not screened.settled
    assert screened.flagged["optimization"].tolist() == stand_ins.fits[-1] == [gross_errors.MAX_ROUNDS - 1]
    assert gross_errors.MAX_ROUNDS - 1 not in screened.data["optimization"].rows.tolist()
    warning = screened_selection.gross_warnings(screened.flagged, screened.screens, screened.settled)
    assert warning == [
        f"the gross-error screen did not settle: the final model, fitted without rows [{gross_errors.MAX_ROUNDS - 1}], "
        f"finds rows [{gross_errors.MAX_ROUNDS}]"
    ]
    # with the rounds: their selections differed (the stand-in adds an effect on every other fit), and
    # a few rows left out deciding the model is said
    warnings = screened_selection.gross_warnings(screened.flagged, screened.screens, screened.settled, screened.history)
    assert warnings[0] == warning[0] and len(warnings) == 2
    assert warnings[1].startswith(
        "the selection changed between the gross-error screen's rounds (without 1 row: link_geometry; "
        "without 1 row: nothing;"
    )


def test_a_selection_the_same_in_every_round_gives_no_warning():
    history = [{"fitted_without": [0], "found": [1], "added": ["link_geometry"]}] * 2
    screens = {
        s: types.SimpleNamespace(systematic=False, gross=np.asarray([1])) for s in ("optimization", "validation")
    }
    flagged = {"optimization": np.asarray([1]), "validation": np.asarray([], dtype=int)}
    assert screened_selection.gross_warnings(flagged, screens, True, history) == []
