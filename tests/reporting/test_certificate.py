"""The calibration certificate: numbers from the result files, an honest uncertainty of a mean
error (CR2, t), both models' corrections with U (95 %), and the warnings a user must read."""

import dataclasses

import numpy as np
import pandas as pd

from remaster.inference.laplace_report import LaplaceReport
from remaster.inference.uncertainty import coverage_factor
from remaster.reporting import certificate

from ..conftest import loop_report


def test_the_pose_clustered_uncertainty_of_a_mean_error_covers_95_percent():
    """Configurations of one pose share most of their error: a naive std / sqrt(n) would be too
    small by sqrt(configurations per pose); the clustered u (CR2) with k = t(poses - 1) gives about
    95 % coverage."""
    rng = np.random.default_rng(5)
    covered, naive_covered = [], []
    poses = np.repeat(np.arange(30), 4)
    for _ in range(2000):
        errors = 2.0 + rng.normal(0, 1.0, 30)[poses] + rng.normal(0, 0.3, len(poses))
        mean, u, count, dof = certificate.mean_with_uncertainty(errors, poses)
        covered.append(abs(mean - 2.0) <= coverage_factor(dof) * u)
        naive_covered.append(abs(mean - 2.0) <= 2 * errors.std(ddof=1) / np.sqrt(count))
    assert dof == 29 and 0.935 <= np.mean(covered) <= 0.965  # binomial sd 0.5 %; equal poses: exactly t(29)
    assert np.mean(naive_covered) < 0.8
    assert np.isnan(certificate.mean_with_uncertainty([1.0, 2.0], [0, 0])[1])  # one pose: no u


def _inputs(outliers=(), closed=True):
    laplace = LaplaceReport(
        ("zero_offsets.q2",),
        np.zeros(1),
        np.ones(1),
        np.eye(1),
        1e-3,
        1e-3,
        1e-4,
        ("zero_offsets.q1", "zero_offsets.q2"),
        {"zero_offsets.q1": 0.0},
        (),
        tuple(outliers),
        (4,),
        40,
    )
    rows = []
    for method, level in ((certificate.BEFORE, 3.0), (certificate.AFTER, 1.0)):
        for k in range(20):
            rows.append(
                {
                    "set": "validation",
                    "registration": certificate.AS_IS,
                    "method": method,
                    "row": 100 + k,
                    "pose": k // 2,
                    "error_mm": level + 0.1 * (k % 2) + 0.01 * k,
                }
            )
    errors = pd.DataFrame(rows)
    residuals = pd.DataFrame(
        {
            "when": "after",
            "set": "validation",
            "point": np.arange(20),
            "row": 100 + np.arange(20),
            "x_m": 2e-5 + 1e-6 * (np.arange(20) // 2),
            "y_m": 0.0,
            "z_m": 0.0,
        }
    )  # rows of 10 poses
    claims = pd.DataFrame(
        [
            {
                "model": m,
                "configurations": c,
                "frame": "registered",
                "noise": "with noise",
                "mean_mm": v,
                "p95_mm": 2 * v,
                "p95_bound_mm": 3 * v,
                "p95_bound_data_mm": 3 * v * (0.1 if (m, c) == ("loop", "random") else 0.9),
                "count": 100,
            }
            for m, c, v in (
                ("paper", "optimization", 1.0),
                ("loop", "optimization", 0.02),
                ("paper", "random", 1.1),
                ("loop", "random", 0.5),
                ("paper", "domain", 1.05),
                ("loop", "domain", 0.03),
            )
        ]
    )
    workspace = {
        "draws": 20,
        "prior_dominated": ["link_geometry.F2.x"],
        "next_campaign_should_add": [
            "joint 2 over more of its range (measured: held at 0 deg)",
            "poses that move link_geometry.F2.x (the data barely moved them from their prior)",
        ],
        "holds": {"loop": {"holds": "inside the measured ranges"}},
        "domain": {
            "ranges": "q1 -150 to 160 deg (90 % of its range), q2 held at 0 deg",
            "held_joints": ["q2"],
            "tool_axis_spread_deg": 17.6,
            "covers_the_limits": False,
            "holds": "inside the measured ranges: q1 -150 to 160 deg (90 % of its range), q2 held at 0 deg",
        },
        "coverage": {"joint_range_fraction": [0.9, 0.0], "tool_axis_spread_deg": 17.6},
        "warnings": ["the next campaign must add: joint 2 over more of its range (measured: held at 0 deg)"],
        "held_note": "",
    }
    verdict = "closed" if closed else "not closed: 0.1 mm left per axis"
    refit = "the MCMC refit did not meet R-hat <= 1.05 and ESS >= 200 after 4 runs (last: R-hat 1.079, ESS 71)"
    loop = loop_report(
        effects=["joint_compliance"],
        closure={"closed": closed, "verdict": verdict},
        warnings=([] if closed else [f"loop {verdict}"]) + [refit],
        gross_errors={"optimization": list(outliers), "validation": [], "with_flagged_rows": {}},
    )
    offsets = pd.DataFrame(
        [
            {
                "joint": "j1",
                "model": "paper",
                "correction_deg": 0.0,
                "std_deg": np.nan,
                "status": "held: not identifiable",
            },
            {
                "joint": "j2",
                "model": "paper",
                "correction_deg": 0.19,
                "std_deg": 0.009,
                "u_between_deg": 0.0,
                "U_deg": 0.018,
                "k": 2.0,
                "status": "estimated",
            },
            {
                "joint": "j2",
                "model": "loop",
                "correction_deg": 0.2,
                "std_deg": 0.0001,
                "u_between_deg": 0.002,
                "U_deg": 0.0045,
                "k": 2.26,
                "status": "estimated",
            },
        ]
    )
    return certificate.CertificateInputs(laplace, errors, residuals, claims, workspace, loop, offsets)


SUMMARY = {
    "campaign": "c",
    "date": "2020-01-01",
    "robot": {"name": "arm", "serial": "S-1", "joints": ["j1", "j2"]},
    "sensors": {"laser_tracker": {"kind": "laser_tracker"}},
}


def test_a_certificate_says_before_after_corrections_and_warnings():
    cert = certificate.certificate(SUMMARY, {"laser_tracker": _inputs(outliers=(7,), closed=False)})
    assert "serial S-1" in cert.heading[0] and "40 points used" in cert.heading[1] and "1 not seen" in cert.heading[1]
    accuracy = cert.accuracy.set_index(["Where", "Model"])
    before = accuracy.loc[("validation set (measured)", "controller's zero-offsets")]
    assert before["mean (mm)"] == np.mean([3.0 + 0.1 * (k % 2) + 0.01 * k for k in range(20)])
    assert before["points"] == 20 and before["U(mean) (mm)"] > 0
    loop = accuracy.loc[("validation set (measured)", "loop-closed (added: joint_compliance (robot))")]
    pose_means = 0.02 + 0.001 * np.arange(10)  # the loop's rows found their poses through the table's rows
    assert np.isclose(loop["mean (mm)"], pose_means.mean())
    # equal poses: CR2 is the spread of the pose means / sqrt(10), with k = t_0.975(9)
    assert np.isclose(loop["U(mean) (mm)"], 2.262157 * pose_means.std(ddof=1) / np.sqrt(10))
    # a claim's p95 is the bound on this arm's own 95th percentile, not the pooled quantile (2 x mean)
    limits = "claimed across the joint limits (priors where the data did not reach)"
    assert accuracy.loc[(limits, "loop-closed"), "p95 (mm)"] == 1.5
    assert accuracy.loc[("claimed near the measured configurations", "loop-closed"), "p95 (mm)"] == 3 * 0.03
    # both models, the loop-closed one first, each U as controller_offsets.csv gives it
    corrections = cert.corrections
    assert corrections["Model"].str.startswith("loop-closed").tolist() == [True, False, False]
    loop_j2, paper_j2 = corrections.iloc[0], corrections.iloc[2]
    assert loop_j2["U(Correction) (deg)"] == 0.0045 and loop_j2["u_between (deg)"] == 0.002
    assert paper_j2["U(Correction) (deg)"] == 0.018 and paper_j2["Model"].startswith("zero-offsets only")
    held = corrections.iloc[1]
    assert np.isnan(held["Correction (deg)"]) and held["Status"].startswith("held")
    verdict = cert.verdicts.iloc[0]
    assert (
        verdict["U(Before: mean) (mm)"] == before["U(mean) (mm)"]
        and verdict["U(After: mean) (mm)"] == loop["U(mean) (mm)"]
    )
    detail = cert.details[0]
    assert detail["Holds"] == (
        "inside the measured ranges: q1 -150 to 160 deg (90 % of its range), q2 held at 0 deg; "
        + certificate.NOT_DETERMINED
    )
    assert detail["After: model"].startswith("loop-closed")
    assert verdict["Near the measured configurations: p95 (mm)"] == 3 * 0.03
    # joint 2 never turned: the number across the limits would be the priors', so none is given
    assert verdict["Across the joint limits: p95 (mm)"] == certificate.NOT_DETERMINED_CELL
    # the verdict table holds its numbers; its words are in the brief line and certificate.json
    assert tuple(cert.verdicts.columns) == certificate.VERDICT_COLUMNS
    assert any("optimization set: 1 rows flagged as gross errors" in w and "[7]" in w for w in cert.warnings)
    assert any(w.startswith("Laser Tracker: loop closure: loop not closed") for w in cert.warnings)
    assert any("loop closure: the MCMC refit did not meet" in w for w in cert.warnings)
    assert "Laser Tracker: the next campaign must add: joint 2 over more of its range (measured: held at 0 deg)" in (
        cert.warnings
    )
    assert cert.warnings[0].endswith(
        "over the joint ranges measured: q1 -150 to 160 deg (90 % of its range), q2 held at 0 deg; every measured "
        "tool axis within 18 deg of one direction; beyond them, the claim across the joint limits carries the "
        "priors of what the data did not reach"
    )
    text = certificate.to_markdown(cert)
    assert text.startswith("# Calibration certificate: c") and "| j2 | 0.190 | 0.018 |" in text
    # a claim's points are its configurations (count / draws), not draws times configurations
    assert accuracy.loc[(limits, "loop-closed"), "points"] == 5
    # the first screen: a line per sensor before any table, the method after the tables
    brief = cert.brief[0]
    assert brief.startswith("Laser Tracker: acceptance not tested; error after ")
    assert "not determined: the accuracy across the joint limits" in brief and "1 parameter the data" in brief
    assert "the next campaign should add: joint 2 over more of its range" in brief
    assert text.index(brief) < text.index("## Verdict") < text.index("## How these numbers were made")
    assert text.index("## How these numbers were made") < text.index("Errors are post-registration distances")


def test_near_the_data_the_priors_can_decide_and_the_certificate_then_gives_no_number():
    """The loop-closed claim near the measured configurations, 0.09 mm, of which the data determine
    0.009 mm: the priors' statement, so the verdict leaves it blank and says why, and the first
    screen says the accuracy holds at the measured configurations only."""
    inputs = _inputs()
    claims = inputs.workspace_accuracy.copy()
    near = (claims["model"] == "loop") & (claims["configurations"] == "domain")
    claims.loc[near, "p95_bound_data_mm"] = 0.009
    cert = certificate.certificate(SUMMARY, {"laser_tracker": dataclasses.replace(inputs, workspace_accuracy=claims)})
    verdict = cert.verdicts.iloc[0]
    assert verdict["Near the measured configurations: p95 (mm)"] == certificate.NOT_DETERMINED_CELL
    assert cert.details[0]["Holds"].endswith(certificate.NEAR_NOT_DETERMINED)
    assert "holds at the measured configurations" in cert.brief[0]
    assert "the accuracy near the measured configurations (the priors supply most of its bound)" in cert.brief[0]


def _cross_check(disagree: dict[str, str]) -> pd.DataFrame:
    """A cross_check.csv as `cross_check.cross_check` writes it: every parameter, `disagreement` the
    methods that disagree on it ("" where none)."""
    names = ["zero_offsets.q2", "noise.sigma"]
    return pd.DataFrame(
        {
            "parameter": names,
            "z_emcee": [5.2 if "emcee" in disagree.get(n, "") else 0.3 for n in names],
            "disagrees_emcee": ["emcee" in disagree.get(n, "") for n in names],
            "disagreement": [disagree.get(n, "") for n in names],
        }
    )


def test_samplers_that_disagree_are_in_the_verdict_and_the_warnings(tmp_path):
    """A disagreement no longer stops the campaign: the certificate is made, its verdict says the
    fit is not confirmed by a second sampler and names the parameter and the method, and so do its
    warnings; agreeing samplers confirm it; no cross-check read says so."""
    from remaster import files

    path = files.write_csv(tmp_path / "cross_check.csv", _cross_check({"zero_offsets.q2": "emcee, laplace"}))
    inputs = dataclasses.replace(_inputs(), cross_check=files.read_csv(path))
    cert = certificate.certificate(SUMMARY, {"laser_tracker": inputs})
    verdict = cert.details[0]["Samplers"]
    assert verdict == (
        "the fit is not confirmed by a second sampler: they disagree on zero_offsets.q2 (emcee, laplace)"
    )
    warning = next(w for w in cert.warnings if "not confirmed" in w)
    assert (
        warning.startswith("Laser Tracker: the fit is not confirmed by a second sampler")
        and "zero_offsets.q2" in warning
    )
    assert "not confirmed by a second sampler" in certificate.to_markdown(cert)
    # agreeing samplers, as read back from a file whose `disagreement` column is empty (NaN)
    path = files.write_csv(tmp_path / "agree.csv", _cross_check({}))
    agreed = certificate.certificate(
        SUMMARY, {"laser_tracker": dataclasses.replace(inputs, cross_check=files.read_csv(path))}
    )
    assert agreed.details[0]["Samplers"] == certificate.CONFIRMED
    assert "sampler" not in agreed.brief[0]
    assert not any("not confirmed" in w for w in agreed.warnings)
    unchecked = certificate.certificate(SUMMARY, {"laser_tracker": _inputs()})
    assert unchecked.details[0]["Samplers"] == certificate.NOT_CHECKED


def test_certificate_rows_take_missing_values_without_a_crash():
    """None and NaN where numbers or sections are expected: blanks in the certificate, no crash."""
    inputs = _inputs()
    offsets = inputs.controller_offsets.copy().astype(object)
    offsets.loc[1, "U_deg"] = None
    offsets.loc[1, "correction_deg"] = np.nan
    loop = dataclasses.replace(inputs.loop, closure={}, warnings=[])
    inputs = dataclasses.replace(inputs, controller_offsets=offsets, loop=loop)
    cert = certificate.certificate(SUMMARY, {"laser_tracker": inputs})
    paper_j2 = cert.corrections.iloc[2]
    assert np.isnan(paper_j2["U(Correction) (deg)"]) and np.isnan(paper_j2["Correction (deg)"])
    assert cert.details[0]["Loop"] == ""
    assert certificate.to_markdown(cert).startswith("# Calibration certificate: c")
    # no validation rows at all: the verdict's after-values are blank, not an IndexError
    empty = dataclasses.replace(inputs, configuration_errors=inputs.configuration_errors.iloc[:0])
    verdict = certificate.certificate(SUMMARY, {"laser_tracker": empty}).verdicts.iloc[0]
    assert np.isnan(verdict["Before: mean (mm)"]) and np.isnan(verdict["After: p95 (mm)"])


def test_a_held_registration_parameter_and_each_held_combination_are_warnings():
    inputs = _inputs()
    statement = "zero_offsets.q7 is held at the controller's value: 1 deg of it changes no measured point"
    laplace = dataclasses.replace(
        inputs.laplace, held={"zero_offsets.q1": 0.0, "registration.y": 0.0}, held_statements=(statement,)
    )
    cert = certificate.certificate(SUMMARY, {"laser_tracker": dataclasses.replace(inputs, laplace=laplace)})
    assert any("registration.y held" in w for w in cert.warnings)
    assert f"Laser Tracker: {statement}" in cert.warnings
    assert not any(
        "do not determine the registration" in w
        for w in certificate.certificate(SUMMARY, {"laser_tracker": _inputs()}).warnings
    )


def _acceptance(verdict, diagnosis):
    from remaster.evaluation.acceptance import Acceptance

    checks = {m: {"passed": verdict == "pass", "p_value": 0.0} for m in ("loop", "paper")}
    text = "fail: ... the calibration is not confirmed" if diagnosis else "pass"
    return Acceptance(
        "laser_tracker",
        verdict,
        diagnosis,
        text,
        None,
        checks,
        0.01,
        0.95,
        10.0,
        100,
        20,
        (),
        (text,) if diagnosis else (),
    )


def test_the_acceptance_test_gives_the_verdict_and_its_warning_and_chooses_no_model():
    """A failure on the validation set is a line of the verdict and a warning; 'After' stays the
    loop-closed model's, chosen before the validation set was read, whatever the test says."""
    inputs = _inputs()
    first = certificate.certificate(SUMMARY, {"laser_tracker": inputs})
    untested, model = first.verdicts.iloc[0], first.details[0]["After: model"]
    assert untested["Acceptance"] == certificate.NOT_TESTED and model.startswith("loop-closed")
    passed = dataclasses.replace(inputs, acceptance=_acceptance("pass", None))
    verdict = certificate.certificate(SUMMARY, {"laser_tracker": passed}).verdicts.iloc[0]
    assert verdict["Acceptance"] == "pass" and verdict["After: mean (mm)"] == untested["After: mean (mm)"]
    failed = dataclasses.replace(inputs, acceptance=_acceptance("fail", "not_confirmed"))
    cert = certificate.certificate(SUMMARY, {"laser_tracker": failed})
    verdict = cert.verdicts.iloc[0]
    assert verdict["Acceptance"] == "fail: the calibration is not confirmed"
    assert cert.details[0]["After: model"] == model and f"on the validation set; model after: {model};" in cert.brief[0]
    assert verdict["After: mean (mm)"] == untested["After: mean (mm)"]
    assert any(w.startswith("Laser Tracker: fail: ") and "not confirmed" in w for w in cert.warnings)
    assert "| fail: the calibration is not confirmed |" in certificate.to_markdown(cert)


def test_names_from_campaign_yaml_are_text_in_the_markdown_never_markup():
    """campaign.yaml's robot serial, the campaign and the robot name reach certificate.md: raw HTML
    or a Markdown link in them must show as text (Markdown viewers render HTML)."""
    script = "<script>alert(1)</script>"
    summary = {
        **SUMMARY,
        "campaign": f"c{script}",
        "robot": {**SUMMARY["robot"], "name": "[arm](javascript:alert(1))", "serial": script},
    }
    cert = certificate.certificate(summary, {"laser_tracker": _inputs()})
    text = certificate.to_markdown(cert)
    assert "<script" not in text and "](" not in text.replace("\\](", "")
    assert text.startswith("# Calibration certificate: c&lt;script&gt;alert(1)&lt;/script&gt;")
    assert "serial &lt;script&gt;alert(1)&lt;/script&gt;" in text and "\\[arm\\](javascript:alert(1))" in text
    # the verdict table as tables/certificate_verdict.md writes it (the report's overview) names the campaign
    from remaster.reporting.tables import to_markdown

    assert "| c&lt;script&gt;alert(1)&lt;/script&gt; |" in to_markdown(cert.verdicts)


def test_the_certificate_says_which_urdf_to_load_and_how_far_each_is_from_the_loop_model():
    inputs = _inputs()
    far = {
        name: {"median_mm": m, "p95_mm": 2 * m, "max_mm": 3 * m}
        for name, m in (("paper.urdf", 0.55), ("loop.urdf", 0.54), ("rigid.urdf", 0.22), ("ik.urdf", 0.31))
    }
    urdfs = {"configurations": 1000, "distance_from_loop_model_mm": far, "not_followed": "the residual GP"}
    workspace = {**inputs.workspace, "urdfs": urdfs}
    cert = certificate.certificate(SUMMARY, {"laser_tracker": dataclasses.replace(inputs, workspace=workspace)})
    line = next(w for w in cert.warnings if "rigid.urdf" in w)
    assert line.startswith("Laser Tracker: a tool that loads a URDF alone should load rigid.urdf")
    assert "at the tool" not in line  # a report from before the tools were scored names none
    assert "rigid.urdf 0.22 mm median, 0.66 mm at most; loop.urdf 0.54 mm median" in line
    assert line.endswith(
        "stays exact on ik.urdf (zero-offsets, base and tool only): ik.urdf 0.31 mm median, 0.93 mm at most"
    )
    assert not any("rigid.urdf" in w for w in certificate.certificate(SUMMARY, {"laser_tracker": inputs}).warnings)


def test_the_certificate_gives_each_urdfs_distance_at_the_users_tools():
    inputs = _inputs()
    far = {
        name: {"median_mm": m, "p95_mm": 2 * m, "max_mm": 3 * m}
        for name, m in (("rigid.urdf", 0.2), ("ik.urdf", 0.3), ("paper.urdf", 0.5), ("loop.urdf", 0.4))
    }
    at_tools = {"gripper": {**far, "rigid.urdf": {"median_mm": 0.25, "p95_mm": 0.5, "max_mm": 0.7}}}
    urdfs = {
        "configurations": 1000,
        "distance_from_loop_model_mm": far,
        "not_followed": "the residual GP",
        "tools_m": {"gripper": [0.1, 0.0, 0.1]},
        "distance_at_tools_mm": at_tools,
    }
    workspace = {**inputs.workspace, "urdfs": urdfs}
    cert = certificate.certificate(SUMMARY, {"laser_tracker": dataclasses.replace(inputs, workspace=workspace)})
    line = next(w for w in cert.warnings if "rigid.urdf" in w)
    assert line.endswith(
        "at the tool 'gripper' (100, 0, 100 mm in the flange frame): rigid.urdf 0.25 mm median, 0.7 mm at most; "
        "ik.urdf 0.3 mm median, 0.9 mm at most; paper.urdf 0.5 mm median, 1.5 mm at most"
    )


def test_a_joint_held_as_not_determined_says_so_in_its_corrections():
    """A zero-offset the zero-offset fit held because the data determine it no better than the
    controller's marks: its held correction rows give that reason, not 'not identifiable'."""
    inputs = _inputs()
    reason = "not determined: std 2.67 deg > 0.5 deg"
    laplace = dataclasses.replace(inputs.laplace, held_reasons={"zero_offsets.q1": reason})
    cert = certificate.certificate(SUMMARY, {"laser_tracker": dataclasses.replace(inputs, laplace=laplace)})
    held = cert.corrections[cert.corrections["Joint"] == cert.corrections["Joint"].iloc[1]]
    assert held["Status"].tolist() == [f"held: {reason}"] * len(held) and len(held) >= 1
    assert np.isnan(held["Correction (deg)"]).all()
    plain = certificate.certificate(SUMMARY, {"laser_tracker": inputs}).corrections.iloc[1]
    assert plain["Status"] != f"held: {reason}"


def test_the_certificate_names_the_inputs_read_from_outside_the_campaign_folder():
    outside = ["kuka_iiwa14.urdf -> /data/robots/kuka_iiwa14.urdf"]
    cert = certificate.certificate({**SUMMARY, "inputs_outside_the_folder": outside}, {"laser_tracker": _inputs()})
    line = next(h for h in cert.heading if h.startswith("Read from outside the campaign folder"))
    assert line.endswith("this certificate): kuka_iiwa14.urdf -> /data/robots/kuka_iiwa14.urdf.")
    plain = certificate.certificate(SUMMARY, {"laser_tracker": _inputs()})
    assert not any("outside the campaign folder" in h for h in plain.heading)
