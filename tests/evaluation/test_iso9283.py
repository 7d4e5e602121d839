"""ISO 9283 position accuracy and repeatability against known answers."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from remaster.evaluation import iso9283
from remaster.evaluation.accuracy import REGISTRATION_AS_FITTED, VERNIER_LEAST_SQUARES

from ..conftest import REPO


def test_rp_of_isotropic_noise_is_l_bar_plus_three_s_and_ap_is_the_offset():
    """30 cycles to each of 200 commands, attained = command + b + N(0, s^2 I3): AP = |b| up to
    the barycentre's noise, and l = |e - mean e| is Maxwell-like, so RP -> s (2 sqrt(2 / pi) + 3
    sqrt((3 pi - 8) / pi)) = 3.617 s."""
    rng = np.random.default_rng(11)
    s, bias, cycles = 1e-5, np.array([3e-5, -4e-5, 0.0]), 30
    groups = np.repeat(np.arange(200), cycles)
    residuals = bias + s * rng.standard_normal((len(groups), 3))
    poses = iso9283.pose_characteristics(residuals, groups)
    assert (poses["cycles"] == cycles).all()
    np.testing.assert_allclose(poses["AP"].mean(), 5e-5, rtol=0.02)
    # l from a 30-cycle barycentre is shrunk by sqrt(29 / 30) (the barycentre is estimated)
    expected = s * np.sqrt(29 / 30) * (2 * np.sqrt(2 / np.pi) + 3 * np.sqrt((3 * np.pi - 8) / np.pi))
    np.testing.assert_allclose(poses["RP"].mean(), expected, rtol=0.03)
    single = iso9283.pose_characteristics(residuals[:3], [0, 1, 2])  # one cycle: AP is the error, no RP
    np.testing.assert_allclose(single["AP"], np.linalg.norm(residuals[:3], axis=1))
    assert single["RP"].isna().all()


def _errors(rows, residuals_mm):
    frame = []
    for method in (VERNIER_LEAST_SQUARES, "Bayesian"):
        for row, e in zip(rows, residuals_mm):
            frame.append(
                {
                    "set": "validation",
                    "registration": REGISTRATION_AS_FITTED,
                    "method": method,
                    "row": row,
                    "residual_x_mm": e[0],
                    "residual_y_mm": e[1],
                    "residual_z_mm": e[2],
                }
            )
    return pd.DataFrame(frame)


def test_the_table_finds_repeated_configurations_by_their_readings_or_says_rp_is_not_available():
    readings = pd.DataFrame({"q1": [0.1, 0.2, 0.1, 0.3, 0.1], "q2": [0.5, 0.5, 0.5, 0.0, 0.5]})
    residuals = np.array([[1.0, 0, 0], [2, 0, 0], [1.2, 0, 0], [0, 3, 0], [0.8, 0, 0]])
    sensor = SimpleNamespace(table=readings, joint_columns=("q1", "q2"))  # what the table reads of a SensorData
    table = iso9283.iso9283_table({"laser_tracker": sensor}, {"laser_tracker": _errors(range(5), residuals)})
    row = table.iloc[1]
    assert row["Model"] == "remastered zero-offsets" and row["configurations"] == 3 and row["cycles"] == 5
    assert row["AP max (mm)"] == 3.0 and np.isclose(row["AP mean (mm)"], (1.0 + 2.0 + 3.0) / 3)
    deviations = np.abs([0.0, 0.2, -0.2])  # the three cycles of (0.1, 0.5) about their barycentre
    assert (
        np.isclose(row["RP max (mm)"], deviations.mean() + 3 * deviations.std(ddof=1))
        and "1 configurations measured 3 to 3" in row["note"]
    )
    first_two = SimpleNamespace(table=readings.iloc[:2], joint_columns=("q1", "q2"))
    once = iso9283.iso9283_table({"laser_tracker": first_two}, {"laser_tracker": _errors(range(2), residuals)})
    assert once["RP mean (mm)"].isna().all() and once["note"].str.startswith("RP not available").all()


def test_the_per_pose_report_gives_each_repeated_configuration_its_axes_and_rp():
    readings = pd.DataFrame({"q1": [0.1, 0.2, 0.1, 0.3, 0.1], "q2": [0.5, 0.5, 0.5, 0.0, 0.5], "pose": [7, 8, 7, 9, 7]})
    residuals = np.array([[1.0, 0, -1], [2, 0, 0], [1.2, 0.3, -1], [0, 3, 0], [0.8, -0.3, -1]])
    sensor = SimpleNamespace(table=readings, joint_columns=("q1", "q2"))
    table = iso9283.iso9283_poses_table({"laser_tracker": sensor}, {"laser_tracker": _errors(range(5), residuals)})
    assert len(table) == 2 and list(table["Model"]) == ["controller's zero-offsets", "remastered zero-offsets"]
    row = table.iloc[1]
    assert (row["first row"], row["plan pose"], row["cycles"]) == (0, 7, 3)
    np.testing.assert_allclose(row[["APx (mm)", "APy (mm)", "APz (mm)"]].to_numpy(float), [1.0, 0.0, -1.0], atol=1e-12)
    assert np.isclose(row["AP (mm)"], np.sqrt(2.0))
    deviations = np.linalg.norm(residuals[[0, 2, 4]] - [1.0, 0.0, -1.0], axis=1)
    assert np.isclose(row["RP (mm)"], deviations.mean() + 3 * deviations.std(ddof=1))
    once = SimpleNamespace(table=readings.iloc[:2], joint_columns=("q1", "q2"))
    none = iso9283.iso9283_poses_table({"laser_tracker": once}, {"laser_tracker": _errors(range(2), residuals)})
    assert len(none) == 2 and none["note"].str.startswith("no configuration is measured more than once").all()


def test_every_group_at_once_is_each_group_by_itself():
    """Groups of 1 to 6 cycles interleaved in the rows: AP per axis and overall, and RP = l-bar + 3 S
    (NaN for one cycle), as each group's own rows give them."""
    rng = np.random.default_rng(5)
    groups = rng.permutation(np.repeat(np.arange(40), rng.integers(1, 7, size=40)))
    residuals = rng.normal(0.0, 1e-4, (len(groups), 3)) + rng.normal(0.0, 1e-3, (40, 3))[groups]
    table = iso9283.pose_characteristics(residuals, groups).set_index("group")
    for label in range(40):
        e = residuals[groups == label]
        centre = e.mean(axis=0)
        spread = np.linalg.norm(e - centre, axis=1)
        row = table.loc[label]
        assert row["cycles"] == len(e)
        np.testing.assert_allclose(row[["APx", "APy", "APz"]].to_numpy(float), centre, rtol=1e-10)
        assert row["AP"] == pytest.approx(np.linalg.norm(centre), rel=1e-10)
        if len(e) == 1:
            assert np.isnan(row["RP"])
        else:
            assert row["RP"] == pytest.approx(spread.mean() + 3.0 * spread.std(ddof=1), rel=1e-9)


def test_the_per_pose_report_names_the_cube_points_p1_to_p5_and_lists_them_in_that_order(tmp_path, iiwa):
    """A campaign of `remaster plan --objective iso9283`, measured in another order (each cycle
    P5, P2, P1, P4, P3): its five repeated configurations are named by where the nominal robot puts
    the flange, P1 the cube's centre, P2..P5 its corners as `planning.iso9283_points` places them,
    and listed P1..P5 (they used to be listed by an internal label, e.g. plan poses 4, 1, 0, 3, 2,
    unnamed). Without the chain, or for a design that is no ISO cube, no pose is named and the rows
    follow the order of first measurement."""
    from remaster import cli

    plan = tmp_path / "iso.csv"
    status = cli.main(
        ["plan", "--urdf", str(REPO / "data" / "robots" / "kuka_iiwa14.urdf"), "--base", "iiwa_link_0", "--flange",
         "iiwa_link_ee", "--sensor-origin", "1.6", "0.5", "1.0", "--marker", "-0.1", "0", "0.02", "--objective",
         "iso9283", "--cube-centre", "0.6", "0.2", "0.5", "--cube-edge", "0.2", "--set", "validation", "--cycles",
         "3", "--out", str(plan)]
    )  # fmt: skip
    assert status == 0
    order = [4, 1, 0, 3, 2]  # P5, P2, P1, P4, P3 in each cycle
    table = pd.read_csv(plan)
    table = table.iloc[[5 * cycle + k for cycle in range(3) for k in order]].reset_index(drop=True)
    joints = tuple(f"q{j}" for j in range(1, 8))
    sensor = SimpleNamespace(table=table, joint_columns=joints)
    rng = np.random.default_rng(3)
    errors = {"laser_tracker": _errors(range(len(table)), rng.normal(0.0, 0.01, (len(table), 3)))}

    named = iso9283.iso9283_poses_table({"laser_tracker": sensor}, errors, iiwa)
    for model in ("controller's zero-offsets", "remastered zero-offsets"):
        rows = named[named["Model"] == model]
        assert rows["ISO pose"].tolist() == ["P1", "P2", "P3", "P4", "P5"]
        # the plan's own record of each row's point agrees with the name given from the geometry
        assert table["iso_pose"].iloc[rows["first row"]].tolist() == ["P1", "P2", "P3", "P4", "P5"]
        assert (rows["cycles"] == 3).all()

    unnamed = iso9283.iso9283_poses_table({"laser_tracker": sensor}, errors)
    rows = unnamed[unnamed["Model"] == "remastered zero-offsets"]
    assert rows["ISO pose"].tolist() == [""] * 5 and rows["first row"].tolist() == [0, 1, 2, 3, 4]
    four = SimpleNamespace(table=table[table["iso_pose"] != "P3"].reset_index(drop=True), joint_columns=joints)
    fewer = {"laser_tracker": _errors(range(12), rng.normal(0.0, 0.01, (12, 3)))}
    assert (iso9283.iso9283_poses_table({"laser_tracker": four}, fewer, iiwa)["ISO pose"] == "").all()
