"""Cross-campaign comparison on hand-made posterior summaries with known answers."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from remaster import files, identity
from remaster.comparing import comparison
from remaster.errors import InputError
from remaster.inference.model import SIGMA
from remaster.loop.result import LoopReport
from remaster.reporting import figures_comparison
from remaster.units import DEG

from ..conftest import REPO, loop_report

HELD = "held: not identifiable"


def summary(means_deg, stds_deg, held=()):
    """A posterior summary (SI, indexed by parameter) of zero-offsets q1..qN plus sigma;
    joints in `held` (1-based) are held at 0 with no std."""
    names = [f"zero_offsets.q{j + 1}" for j in range(len(means_deg))] + [SIGMA]
    mean = [m * DEG for m in means_deg] + [8e-4]
    std = [s * DEG for s in stds_deg] + [1e-5]
    status = ["estimated"] * len(names)
    for j in held:
        mean[j - 1], std[j - 1], status[j - 1] = 0.0, np.nan, HELD
    table = pd.DataFrame(
        {"mean": mean, "std": std, "q2.5": np.nan, "q97.5": np.nan, "status": status},
        index=pd.Index(names, name="parameter"),
    )
    return table


ROBOT = "urdf:kuka_iiwa14.urdf:iiwa_link_0:iiwa_link_ee"
ENTRIES = [
    # kuka-twin-2019 given first: the order of entries does not matter, dates do
    comparison.Entry(
        "kuka-twin-2019",
        "2019-06-18",
        "laser_tracker",
        summary([0.10, 0.34, 0.0], [0.009, 0.009, 0.01], held=[3]),
        ROBOT,
        "laser_tracker",
    ),
    (
        "kuka-twin",
        "2018-06-12",
        "laser_tracker",
        summary([0.10, 0.30, 0.05], [0.009, 0.009, 0.01]),
        ROBOT,
        "laser_tracker",
    ),
    (
        "kuka-twin",
        "2018-06-12",
        "motion_capture",
        summary([0.11, 0.31, 0.10], [0.02, 0.01, 0.01]),
        ROBOT,
        "motion_capture",
    ),
]


def test_robot_identity_of_the_bundled_campaigns():
    twin, twin_2019, compliance = (
        files.read_yaml(REPO / "data" / "raw" / c / "campaign.yaml")
        for c in ("kuka-twin", "kuka-twin-2019", "kuka-compliance")
    )
    # the serial names the physical unit: the twin and its campaign a year later are one robot,
    # kuka-compliance is another iiwa
    assert identity.robot_identity(twin) == identity.robot_identity(twin_2019) == "serial:iiwa14-NIST-01"
    assert identity.robot_identity(twin["robot"]) == "serial:iiwa14-NIST-01"  # the section alone
    assert identity.robot_identity(compliance) == "serial:iiwa14-LAB-02"
    # without a serial, the model: same URDF and frames
    model = {k: v for k, v in twin["robot"].items() if k != "serial"}
    assert identity.robot_identity(model) == ROBOT
    assert identity.robot_identity({**model, "flange": "iiwa_link_7"}) != ROBOT


def test_robot_identity_of_dh_tables():
    rows = [[0.0, math.pi / 2, 0.3, 0.0], [0.4, 0.0, 0.0, 0.0]]
    a = identity.robot_identity({"dh": {"convention": "standard", "rows": rows}})
    b = identity.robot_identity({"dh": {"convention": "standard", "rows": [[v + 1e-12 for v in r] for r in rows]}})
    c = identity.robot_identity({"dh": {"convention": "standard", "rows": [rows[0], [0.41, 0.0, 0.0, 0.0]]}})
    assert a == b != c and a.startswith("dh:standard:")
    with pytest.raises(InputError, match="robot"):
        identity.robot_identity({"name": "no robot"})


def test_zero_offsets_over_time_is_a_long_table_in_degrees():
    table = comparison.zero_offsets_over_time(ENTRIES)
    assert list(table.columns) == comparison.OVER_TIME_COLUMNS
    assert len(table) == 9  # 3 entries x 3 zero-offsets, sigma left out
    assert table["campaign"].tolist() == ["kuka-twin"] * 6 + ["kuka-twin-2019"] * 3
    assert table["sensor"].tolist()[:6] == ["motion_capture"] * 3 + ["laser_tracker"] * 3  # paper order
    row = table[
        (table["campaign"] == "kuka-twin")
        & (table["parameter"] == "zero_offsets.q2")
        & (table["sensor"] == "laser_tracker")
    ].iloc[0]
    assert row["mean_deg"] == pytest.approx(0.30) and row["std_deg"] == pytest.approx(0.009)
    held = table[(table["campaign"] == "kuka-twin-2019") & (table["parameter"] == "zero_offsets.q3")].iloc[0]
    assert held["status"] == HELD and math.isnan(held["std_deg"]) and held["mean_deg"] == 0.0


def test_drift_between_consecutive_campaigns():
    drift = comparison.drift_between(ENTRIES)
    assert list(drift.columns) == comparison.DRIFT_COLUMNS
    drift = drift.set_index("parameter")
    # laser tracker only: motion capture has no later campaign
    assert set(drift["sensor_a"]) == {"laser_tracker"} and set(drift["campaign_a"]) == {"kuka-twin"}
    q1, q2, q3 = (drift.loc[f"zero_offsets.q{j}"] for j in (1, 2, 3))
    assert q2["diff_deg"] == pytest.approx(0.04)
    assert q2["combined_std_deg"] == pytest.approx(0.009 * math.sqrt(2))
    assert q2["z"] == pytest.approx(3.1427, abs=1e-4) and q2["flagged"] and q2["status"] == "compared"
    assert q1["diff_deg"] == pytest.approx(0.0, abs=1e-12) and not q1["flagged"]
    assert q3["status"] == "not comparable: held in kuka-twin-2019 (not identifiable)" and not q3["flagged"]
    assert math.isnan(q3["z"]) and math.isnan(q3["diff_deg"])
    assert (
        not comparison.drift_between(ENTRIES, significance=3.2).set_index("parameter").loc["zero_offsets.q2", "flagged"]
    )


@pytest.mark.parametrize(
    "closed, flagged, both",
    [((True, True), True, True), ((True, False), False, False), ((None, True), True, None), ((None, None), True, None)],
)
def test_a_drift_is_flagged_only_between_loops_that_closed(closed, flagged, both):
    """A loop that did not close carries what its model lacks in its design's own proportions: the
    same z is shown, and flagged as the robot's drift only where both loops closed (where a verdict is
    not known, as before)."""
    entries = [entry._replace(loop_closed=verdict) for entry, verdict in zip(map(_as_entry, ENTRIES[:2]), closed)]
    q2 = comparison.drift_between(entries).set_index("parameter").loc["zero_offsets.q2"]
    assert q2["z"] == pytest.approx(3.1427, abs=1e-4) and q2["status"] == "compared"
    assert q2["flagged"] == flagged
    assert q2["loops_closed"] is None if both is None else bool(q2["loops_closed"]) is both
    over_time = comparison.zero_offsets_over_time(entries)
    assert over_time.groupby("campaign")["loop_closed"].first().to_dict() == {
        "kuka-twin-2019": closed[0],
        "kuka-twin": closed[1],
    }


def _as_entry(item) -> comparison.Entry:
    return item if isinstance(item, comparison.Entry) else comparison.Entry(*item)


def test_drift_only_within_one_robot_and_kind():
    other = [
        (
            "dh-arm-a",
            "2019-01-01",
            "laser_tracker",
            summary([0.5, 0.5, 0.5], [0.01] * 3),
            "dh:standard:x",
            "laser_tracker",
        )
    ]
    drift = comparison.drift_between(ENTRIES + other)
    assert "dh-arm-a" not in set(drift["campaign_a"]) | set(drift["campaign_b"])
    assert comparison.drift_between(ENTRIES[1:]).empty  # one campaign per robot and kind


def test_sensor_agreement_within_each_campaign():
    agreement = comparison.sensor_agreement(ENTRIES)
    assert list(agreement.columns) == comparison.AGREEMENT_COLUMNS
    assert set(agreement["campaign"]) == {"kuka-twin"}  # kuka-twin-2019 has one sensor
    rows = agreement.set_index("parameter")
    assert (rows["sensor_a"] == "motion_capture").all() and (rows["sensor_b"] == "laser_tracker").all()
    q3 = rows.loc["zero_offsets.q3"]  # motion capture 0.10, laser tracker 0.05, std 0.01 each: z = -3.54
    assert q3["diff_deg"] == pytest.approx(-0.05) and q3["z"] == pytest.approx(-0.05 / (0.01 * math.sqrt(2)))
    assert q3["flagged"]
    q1 = rows.loc["zero_offsets.q1"]
    assert q1["z"] == pytest.approx(-0.01 / math.hypot(0.02, 0.009)) and not q1["flagged"]


def test_summary_read_back_from_csv_is_accepted(tmp_path):
    """The workflow stores summaries as CSV with a parameter column."""
    path = files.write_csv(tmp_path / "summary.csv", summary([0.1, 0.2], [0.01, 0.01], held=[2]).reset_index())
    table = comparison.zero_offsets_over_time([("c", "2020-01-01", "laser_tracker", pd.read_csv(path))])
    assert table["status"].tolist() == ["estimated", HELD] and table["robot"].tolist() == ["", ""]
    assert table["kind"].tolist() == ["laser_tracker"] * 2


def test_bad_entries_are_named():
    with pytest.raises(InputError, match="kuka-twin/laser_tracker: date"):
        comparison.zero_offsets_over_time([("kuka-twin", "June 2018", "laser_tracker", summary([0.1], [0.01]))])
    with pytest.raises(InputError, match="kuka-twin/laser_tracker: std"):
        comparison.zero_offsets_over_time(
            [("kuka-twin", "2018-06-12", "laser_tracker", summary([0.1], [0.01]).drop(columns="std"))]
        )
    with pytest.raises(InputError, match="given twice"):
        comparison.zero_offsets_over_time([ENTRIES[1], ENTRIES[1]])


def test_zero_offsets_over_time_figure():
    table = comparison.zero_offsets_over_time(ENTRIES)
    fig = figures_comparison.zero_offsets_over_time_figure(table, "KUKA iiwa 14")
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == 3 and panels[1].get_title() == "zero-offset q2"
    plt.close(fig)
    mixed = comparison.zero_offsets_over_time(
        ENTRIES + [("other", "2019-01-01", "laser_tracker", summary([0.1] * 3, [0.01] * 3), "dh:standard:x")]
    )
    with pytest.raises(ValueError, match="one robot at a time"):
        figures_comparison.zero_offsets_over_time_figure(mixed, "mixed")


def test_over_time_figure_of_a_fleet_keeps_campaigns_of_one_day_apart(recwarn):
    """50 campaigns of one robot on one day (a simulated fleet): one slot each, a readable number
    of labels, and a layout matplotlib could fit (no tight-layout warning)."""
    entries = [
        (
            f"fleet-{i:03d}",
            "2020-03-02",
            "laser_tracker",
            summary([0.1 + 0.001 * i, 0.3], [0.01, 0.01]),
            ROBOT,
            "laser_tracker",
        )
        for i in range(50)
    ]
    fig = figures_comparison.zero_offsets_over_time_figure(comparison.zero_offsets_over_time(entries), "fleet")
    fig.canvas.draw()
    panel = fig.axes[0]
    x = panel.lines[0].get_xdata()
    assert len(np.unique(x)) == 50 and np.all(np.diff(x) > 0)  # in campaign order, none on top of another
    labels = [t.get_text() for t in panel.get_xticklabels()]
    assert len(labels) <= figures_comparison.MAX_LABELS
    assert labels[0] == "fleet-000\n2020-03-02" and labels[-1] == "fleet-049\n2020-03-02"
    assert not [w for w in recwarn if "ight" in str(w.message)], [str(w.message) for w in recwarn]
    plt.close(fig)


def loop(compliance=None, marker=None, q2=(0.3, 0.009)):
    """A loop closure's refit parameter table (display units): registration, zero-offset q2, noise,
    and optionally joint compliance q2 (mean, std in urad/(N m)) and a marker offset x (mm)."""
    rows = [
        ("registration", "registration.x", "mm", 1.0, 0.01, "estimated"),
        ("zero_offsets", "zero_offsets.q2", "deg", *q2, "estimated"),
        ("noise", "noise.sigma", "mm", 0.01, 0.001, "estimated"),
    ]
    if compliance is not None:
        rows += [
            ("joint_compliance", "joint_compliance.q2", "urad/(N m)", *compliance, "estimated"),
            ("joint_compliance", "joint_compliance.q1", "urad/(N m)", 0.0, None, "invisible: no torque"),
        ]
    if marker is not None:
        rows.append(("marker_offset", "marker_offset.x", "mm", *marker, "estimated"))
    return pd.DataFrame(rows, columns=["block", "parameter", "unit", "mean_display", "std_display", "status"])


LOOP_ENTRIES = [
    comparison.Entry(
        "kuka-twin-2019",
        "2019-06-18",
        "laser_tracker",
        summary([0.1], [0.01]),
        ROBOT,
        "laser_tracker",
        loop(compliance=(26.0, 0.5), marker=(0.3, 0.01), q2=(0.34, 0.009)),
    ),
    comparison.Entry(
        "kuka-twin",
        "2018-06-12",
        "laser_tracker",
        summary([0.1], [0.01]),
        ROBOT,
        "laser_tracker",
        loop(compliance=(24.0, 0.5), marker=(0.2, 0.01)),
    ),
    comparison.Entry(
        "kuka-twin",
        "2018-06-12",
        "motion_capture",
        summary([0.1], [0.01]),
        ROBOT,
        "motion_capture",
        loop(compliance=(24.0, 0.5), marker=(5.0, 0.1)),
    ),
    comparison.Entry("no-loop", "2018-01-01", "laser_tracker", summary([0.1], [0.01]), ROBOT, "laser_tracker"),
]


def test_loop_parameters_over_time_keep_display_units_and_leave_out_setup():
    table = comparison.loop_parameters_over_time(LOOP_ENTRIES)
    assert list(table.columns) == comparison.LOOP_OVER_TIME_COLUMNS
    assert "no-loop" not in set(table["campaign"])  # no loop closure, no rows
    assert not table["block"].isin(["registration", "noise"]).any()  # the campaign's set-up, not the robot
    twin_lt = table[(table["campaign"] == "kuka-twin") & (table["sensor"] == "laser_tracker")]
    assert twin_lt["parameter"].tolist() == [
        "zero_offsets.q2",
        "joint_compliance.q2",
        "joint_compliance.q1",
        "marker_offset.x",
    ]  # model order
    compliance = twin_lt.set_index("parameter").loc["joint_compliance.q2"]
    assert compliance["unit"] == "urad/(N m)" and compliance["mean"] == 24.0 and compliance["std"] == 0.5
    assert math.isnan(twin_lt.set_index("parameter").loc["joint_compliance.q1", "std"])  # not estimated
    assert table["campaign"].iloc[0] == "kuka-twin" and table["sensor"].iloc[0] == "motion_capture"  # date, paper order


def test_loop_parameter_drift_compares_models_of_the_same_effects():
    drift = comparison.loop_parameter_drift(LOOP_ENTRIES)
    assert list(drift.columns) == comparison.LOOP_DRIFT_COLUMNS
    assert set(drift["campaign_a"]) == {"kuka-twin"} and set(drift["campaign_b"]) == {"kuka-twin-2019"}
    rows = drift.set_index("parameter")
    compliance = rows.loc["joint_compliance.q2"]  # 24 -> 26, std 0.5 each: z = 2 / 0.707 = 2.83
    assert compliance["diff"] == pytest.approx(2.0) and compliance["z"] == pytest.approx(2 / math.hypot(0.5, 0.5))
    assert compliance["unit"] == "urad/(N m)" and compliance["block"] == "joint_compliance"
    assert not compliance["flagged"] and compliance["status"] == "compared"
    q2 = rows.loc["zero_offsets.q2"]  # 0.30 -> 0.34 deg, std 0.009 each: z = 3.14
    assert q2["flagged"] and q2["z"] == pytest.approx(0.04 / (0.009 * math.sqrt(2)))
    assert rows.loc["marker_offset.x", "status"] == "compared"
    assert rows.loc["joint_compliance.q1", "status"].startswith("not comparable: invisible in kuka-twin (no torque)")


def test_loop_parameter_agreement_leaves_out_each_sensors_own_blocks():
    agreement = comparison.loop_parameter_agreement(LOOP_ENTRIES)
    assert list(agreement.columns) == comparison.LOOP_AGREEMENT_COLUMNS
    assert set(agreement["campaign"]) == {"kuka-twin"}
    rows = agreement.set_index("parameter")
    assert "marker_offset.x" not in rows.index  # each sensor has its own marker
    assert rows.loc["zero_offsets.q2", "status"] == "compared" and rows.loc["zero_offsets.q2", "diff"] == 0.0
    assert rows.loc["joint_compliance.q2", "status"] == "compared" and rows.loc["joint_compliance.q2", "diff"] == 0.0


def test_loop_parameters_of_models_with_different_effects_are_not_compared():
    """A zero-offset fitted beside other effects is another quantity: no z between such models,
    over time and between sensors (marker offsets count, though agreement leaves them out)."""
    differ = [LOOP_ENTRIES[0]._replace(loop=loop(q2=(0.34, 0.009))), *LOOP_ENTRIES[1:3]]
    drift = comparison.loop_parameter_drift(differ)
    expected = "not comparable: models differ (joint_compliance + marker_offset vs none)"
    assert len(drift) == 4 and (drift["status"] == expected).all()
    assert drift["z"].isna().all() and not drift["flagged"].any()
    sensors = [LOOP_ENTRIES[1], LOOP_ENTRIES[2]._replace(loop=loop(compliance=(24.0, 0.5)))]
    agreement = comparison.loop_parameter_agreement(sensors)
    assert (
        agreement["status"] == "not comparable: models differ (joint_compliance vs joint_compliance + marker_offset)"
    ).all() and agreement["z"].isna().all()  # motion capture first
    over_time = comparison.loop_parameters_over_time(differ)
    assert set(over_time["effects"]) == {"joint_compliance + marker_offset", "none"}


def test_loop_parameters_in_other_units_are_not_compared():
    hourly, per_kelvin = (loop().assign(unit=u) for u in ("deg/h", "deg/K"))
    entries = [
        ("a", "2020-01-01", "laser_tracker", summary([0.1], [0.01]), ROBOT, "laser_tracker", hourly),
        ("b", "2021-01-01", "laser_tracker", summary([0.1], [0.01]), ROBOT, "laser_tracker", per_kelvin),
    ]
    drift = comparison.loop_parameter_drift(entries).set_index("parameter")
    assert drift.loc["zero_offsets.q2", "status"] == "not comparable: units differ (deg/h, deg/K)"


def test_loop_entries_from_loop_closure_reports():
    metadata = {
        "c": {
            "date": "2020-01-01",
            "robot": {"urdf": "kuka_iiwa14.urdf"},
            "sensors": {"laser_tracker": {"kind": "laser_tracker"}},
        }
    }
    report = loop_report(loop(compliance=(24.0, 0.5)).replace({np.nan: None}).to_dict("records"))
    entries = comparison.entries_of(
        metadata, {("c", "laser_tracker"): summary([0.1], [0.01])}, {("c", "laser_tracker"): report}
    )
    table = comparison.table("loop_parameters_over_time", entries)
    assert table["parameter"].tolist() == ["zero_offsets.q2", "joint_compliance.q2", "joint_compliance.q1"]
    assert comparison.entries_of(metadata, {("c", "laser_tracker"): summary([0.1], [0.01])})[0].loop is None
    # a report without its refit parameters is refused where it is read, naming the file and the key
    with pytest.raises(InputError, match="c/laser_tracker/loop_closure.json: refit/parameters: missing"):
        loop_report(source="c/laser_tracker/loop_closure.json", refit={})
    with pytest.raises(InputError, match="c/laser_tracker: status"):
        comparison.loop_parameters_over_time([entries[0]._replace(loop=loop().drop(columns="status"))])


def test_loop_effects_over_time_figure():
    table = comparison.loop_parameters_over_time(LOOP_ENTRIES)
    fig = figures_comparison.loop_effects_over_time_figure(table, "KUKA iiwa 14")
    panels = [ax for ax in fig.axes if ax.get_visible()]
    # joint_compliance.q1 is estimated nowhere: no panel
    assert [ax.get_title() for ax in panels] == ["joint_compliance.q2", "marker_offset.x"]
    assert panels[0].get_ylabel() == "urad/(N m)" and panels[1].get_ylabel() == "mm"
    plt.close(fig)
    nothing = comparison.loop_parameters_over_time([e._replace(loop=loop()) for e in LOOP_ENTRIES])
    fig = figures_comparison.loop_effects_over_time_figure(nothing, "KUKA iiwa 14")
    assert "estimated no effect" in fig.axes[0].texts[0].get_text()
    plt.close(fig)


@pytest.mark.slow  # repeat campaigns fitted over seeds
def test_drift_calibration_of_repeat_campaigns_with_honest_and_too_small_stds():
    """Repeat campaigns of one truth: honest stds give z of unit spread and the expected number of
    flags; stds half the truth give z of spread 2 and many more flags."""
    rng = np.random.default_rng(7)
    truth, std = np.array([0.1, 0.3]), np.array([0.01, 0.02])

    def fleet(stated_std):
        estimates = truth + std * rng.standard_normal((200, 2))
        return [
            (f"c{i:03d}", "2020-03-02", "laser_tracker", summary(e, stated_std), ROBOT, "laser_tracker")
            for i, e in enumerate(estimates)
        ]

    honest = comparison.drift_calibration(comparison.drift_between(fleet(std)))
    assert honest["parameter"].tolist() == ["zero_offsets.q1", "zero_offsets.q2"]
    assert (honest["pairs"] == 199).all() and honest["z_mean"].abs().max() < 0.15
    assert np.allclose(honest["z_std"], 1.0, atol=0.15)
    assert np.allclose(honest["expected_flagged"], 199 * 0.0026998, rtol=1e-3) and honest["flagged"].max() <= 5
    overconfident = comparison.drift_calibration(comparison.drift_between(fleet(std / 2)))
    assert np.allclose(overconfident["z_std"], 2.0, atol=0.3) and overconfident["flagged"].min() > 10


def test_a_loop_report_missing_a_key_names_the_file_and_the_key(tmp_path):
    """loop_closure.json is read once into a typed report (`LoopReport.read`): a field the later
    stages need that is missing is named with its file and its path of keys."""
    content = loop_report(effects=["joint_compliance"]).to_json()
    path = tmp_path / "loop_closure.json"
    files.write_json(path, content)
    report = LoopReport.read(path)
    assert report.effects_added == ("joint_compliance",) and report.held_zero_offset_std == pytest.approx(
        np.radians(0.5)
    )
    assert report.source == str(path) and report.sigma_after == pytest.approx(1e-5)
    del content["settings"]["priors"]
    files.write_json(path, content)
    with pytest.raises(InputError, match=r"loop_closure.json: settings/priors: missing in the loop-closure report"):
        LoopReport.read(path)
