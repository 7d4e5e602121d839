"""Named workflow inputs read back by name (`remaster.stage_inputs`), not by position."""

import pytest

from remaster import stage_inputs

INPUTS = {
    "campaign": "raw/c/campaign.yaml",
    "summary__laser_tracker": "r/c/laser_tracker/fit/summary.csv",
    "summary__motion_capture": "r/c/motion_capture/fit/summary.csv",
    "loop__laser_tracker": "r/c/laser_tracker/loop_closure.json",
    "metrics_relative_accuracy__laser_tracker": "r/c/laser_tracker/metrics/relative_accuracy.csv",
}


def test_inputs_are_grouped_by_kind_and_sensor_in_their_order():
    assert stage_inputs.by_sensor(INPUTS, "summary") == {
        "laser_tracker": "r/c/laser_tracker/fit/summary.csv",
        "motion_capture": "r/c/motion_capture/fit/summary.csv",
    }
    assert stage_inputs.sensors(INPUTS, "summary") == ["laser_tracker", "motion_capture"]
    kinds = stage_inputs.by_kind(INPUTS)
    assert list(kinds) == ["summary", "loop", "metrics_relative_accuracy"]
    assert kinds["loop"] == {"laser_tracker": "r/c/laser_tracker/loop_closure.json"}
    assert stage_inputs.by_sensor(INPUTS, "residuals") == {}


def test_pairs_across_campaigns_name_campaign_and_sensor():
    inputs = {"loop__kuka-twin__laser_tracker": "a", "loop__kuka-twin-2019__motion_capture": "b"}
    assert stage_inputs.by_pair(inputs, "loop") == {
        ("kuka-twin", "laser_tracker"): "a",
        ("kuka-twin-2019", "motion_capture"): "b",
    }
    with pytest.raises(ValueError, match="names no campaign"):
        stage_inputs.by_pair({"loop__laser_tracker": "a"}, "loop")
