"""The Snakemake workflow end to end on a tiny simulated campaign: a dry run, a real run, a second
run that has nothing to do, and a run killed half way that completes with the real run's results."""

import os
import re
import shutil
import signal
import subprocess
import time

import pytest

from remaster import audit, files, provenance
from remaster.campaigns import robot_model

from ..conftest import REPO
from .conftest import SNAKEMAKE, run, with_results

pytestmark = pytest.mark.workflow  # runs Snakemake: deselect with -m "not workflow"

CROSS_CAMPAIGN_RULES = {"comparison", "comparison_prediction", "comparison_figures", "audit", "report", "all"}


def planned_rules(root, *targets, config="config.yaml"):
    """rule -> jobs a dry run plans."""
    result = run(root, "-n", "--quiet", "rules", *(("--", *targets) if targets else ()), config=config)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return {rule: int(n) for rule, n in re.findall(r"^(\w+)\s+(\d+)$", result.stdout, flags=re.M) if rule != "total"}


def test_dry_run_plans_a_job_per_campaign_and_stage(tiny):
    """Per sensor: prepare, its three samplers (one job), fit summary, loop closure, acceptance test, calibrated
    outputs, figures;
    per campaign: summary, tables, its figure; across campaigns: comparison (two), their figures,
    audit, report. tiny has two sensors, tiny2 one."""
    planned = planned_rules(tiny)
    sensors, campaigns = 3, 2
    assert planned == {
        "campaign_summary": campaigns,
        "prepare": sensors,
        "sample": sensors,
        "fit_summary": sensors,
        "loop_closure": sensors,
        "acceptance": sensors,
        "calibrated": sensors,
        "figures": sensors,
        "tables": campaigns,
        "campaign_figures": campaigns,
        "comparison": 1,
        "comparison_prediction": 1,
        "comparison_figures": 1,
        "audit": 1,
        "report": 1,
        "all": 1,
    }
    per_campaign = sum(n for rule, n in planned.items() if rule not in CROSS_CAMPAIGN_RULES)
    # the job layout's bound: at most 20 jobs per campaign on average (a two-sensor campaign plans 17, a
    # one-sensor campaign 10) and 10 across
    assert per_campaign == 7 * sensors + 3 * campaigns <= 20 * campaigns
    assert sum(planned.get(rule, 0) for rule in CROSS_CAMPAIGN_RULES) <= 10
    assert not (tiny / "results").exists()


@pytest.mark.slow  # a real workflow run of minutes
def test_real_run_builds_everything_then_nothing(tiny):
    result = run(tiny)
    assert result.returncode == 0, result.stderr[-3000:]
    results = tiny / "results" / "tiny"
    assert (tiny / "results" / "tiny2" / "laser_tracker" / "loop_closure.json").is_file()
    for sensor in ("motion_capture", "laser_tracker"):
        remastering = files.read_json(results / sensor / "remastering.json")
        assert [j["status"] for j in remastering["joints"]][0].startswith("held")
        assert (results / "figures" / f"zero_offset_trace_{sensor}.pdf").is_file()
    for table in ("zero_offsets", "registration_params"):
        for suffix in (".csv", ".md", ".tex"):
            assert (results / "tables" / f"{table}{suffix}").is_file()
    over_time = files.read_csv(tiny / "results" / "comparison" / "loop_parameters_over_time.csv")
    assert set(over_time["campaign"]) == {"tiny", "tiny2"} and "zero_offsets.q2" in set(over_time["parameter"])
    assert "Loop closure over time" in (tiny / "results" / "report.html").read_text(encoding="utf-8")
    again = run(tiny)
    assert again.returncode == 0 and "Nothing to be done" in again.stdout + again.stderr


KILLED_SENSOR = "laser_tracker"  # one sensor's jobs: the other's would add time, not checks


def result_bytes(folder, campaign):
    """The remastering file, the loop closure's tables and samples (its report holds timings), the
    samples and metrics of one sensor of a campaign in a run, as bytes."""
    patterns = [
        f"{campaign}/{KILLED_SENSOR}/remastering.json",
        f"{campaign}/{KILLED_SENSOR}/loop_closure/*",
        f"{campaign}/{KILLED_SENSOR}/fit/summary.csv",
        f"{campaign}/{KILLED_SENSOR}/fit/samples_*.parquet",
        f"{campaign}/{KILLED_SENSOR}/metrics/*.csv",
    ]
    return {str(p.relative_to(folder)): p.read_bytes() for pattern in patterns for p in sorted(folder.glob(pattern))}


@pytest.mark.slow  # a real workflow run of minutes
def test_a_run_killed_half_way_completes_with_identical_results(tiny):
    """A second run of one of the two campaigns into another folder, killed while sampling and
    started again: it finishes, and every result of one of its sensors (samples, loop closure,
    metrics, remastering) equals the first, undisturbed run's to the byte (so the same inputs and
    seed give the same results, whether or not a run was interrupted, and whichever other campaigns
    the configuration lists). The undisturbed run is the real run's above (run again here in case it
    was deselected: then nothing to do); the second asks for those results only: the other sensor,
    figures and the report would add time, not checks."""
    first = tiny / "results"
    wanted = [str(first / "tiny" / KILLED_SENSOR / name) for name in ("remastering.json", "loop_closure.json")]
    undisturbed = run(tiny, "--", *wanted)  # both campaigns configured
    assert undisturbed.returncode == 0, undisturbed.stderr[-3000:]
    killed = with_results(tiny, "results_killed", campaigns=["tiny"])
    targets = [str(tiny / "results_killed" / name) for name in result_bytes(first, "tiny")]
    process = subprocess.Popen(
        SNAKEMAKE + ["-j2", "--configfile", str(tiny / killed), "--", *targets],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while not list((tiny / "results_killed").glob("tiny/*/fit/samples_*.parquet")) and time.monotonic() < deadline:
        time.sleep(0.2)
    os.killpg(process.pid, signal.SIGKILL)  # the whole job tree, as a power cut or a scheduler would
    process.wait()
    assert not all(os.path.exists(target) for target in targets)  # killed before its end
    # what a person does after a kill (README): release the lock the killed run held, run again
    assert run(tiny, "--unlock", config=killed).returncode == 0
    again = run(tiny, "--", *targets, config=killed)
    assert again.returncode == 0, again.stderr[-3000:]
    a, b = result_bytes(first, "tiny"), result_bytes(tiny / "results_killed", "tiny")
    assert a.keys() == b.keys() and len(a) > 15
    assert [name for name in a if a[name] != b[name]] == []


@pytest.mark.slow  # a real workflow run of minutes
def test_the_next_configurations_of_a_calibrated_campaign(tiny, tmp_path):
    """`remaster plan --from-results` on the workflow's own results (the tiny twin's planner held joint
    3): the campaign alone is the n = 0 row, both criteria start from it, and the workspace
    criterion's first proposals move joint 3, which the campaign never did."""
    import numpy as np

    from remaster import cli

    assert run(tiny).returncode == 0  # nothing to do once test_real_run_builds_everything_then_nothing ran
    arguments = [
        "plan",
        "--from-results",
        str(tiny / "results" / "tiny" / "laser_tracker"),
        "--campaign",
        str(tiny / "raw" / "tiny"),
        "--config",
        str(tiny / "config.yaml"),
        "--candidates",
        "20",
        "--evaluation",
        "60",
        "--budget",
        "3",
    ]
    assert cli.main([*arguments, "--out", str(tmp_path / "next.csv")]) == 0
    assert cli.main([*arguments, "--criterion", "robust", "--out", str(tmp_path / "robust.csv")]) == 0
    workspace = files.read_csv(tmp_path / "next_bound.csv")
    robust = files.read_csv(tmp_path / "robust_bound.csv")
    assert list(workspace["n"]) == list(range(4)) and list(robust["n"]) == list(range(4))
    # the same campaign information at n = 0; the first proposal brings the campaign's bound down
    assert robust["bound_p95_mm"].iloc[0] == workspace["bound_p95_mm"].iloc[0] > workspace["bound_p95_mm"].iloc[1]
    assert np.all(np.isfinite(robust["expected_rms_mm"]))
    next_rows = files.read_csv(tmp_path / "next.csv")
    assert abs(next_rows["q3"].iloc[0]) > 0.05 and len(files.read_csv(tmp_path / "robust.csv")) == 3


@pytest.mark.slow  # a real workflow run of minutes
def test_changing_one_campaign_reruns_only_its_jobs(tiny):
    """A new measurement value in one campaign plans only that campaign's jobs and the
    cross-campaign ones (comparison, audit, report); the other campaign's results stay. (The plan
    only: that a rerun completes is the killed run's test.)"""
    first = tiny / "results"
    if not (first / "report.html").exists():
        assert run(tiny).returncode == 0
    parquet = tiny / "raw" / "tiny2" / "laser_tracker.parquet"
    table = files.read_parquet(parquet)
    table.loc[0, "x"] += 1e-6
    files.write_parquet(parquet, table)
    summary = run(tiny, "--summary")
    assert summary.returncode == 0, summary.stderr
    pending = [line.split("\t")[0] for line in summary.stdout.splitlines() if line.endswith("update pending")]
    assert any("/tiny2/" in path for path in pending)
    assert not any("/results/tiny/" in path for path in pending)
    assert all(
        "/tiny2/" in path or "/comparison/" in path or path.endswith(("audit.json", "report.html")) for path in pending
    )


def test_bad_config_is_refused_by_the_schema(tiny):
    files.write_yaml(tiny / "bad.yaml", {"seed": -1})
    result = subprocess.run(
        SNAKEMAKE + ["-n", "--configfile", str(tiny / "bad.yaml")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode != 0 and "seed" in result.stdout + result.stderr


def test_only_a_campaign_given_as_a_dh_table_gets_calibrated_dh_tables(tiny, tmp_path):
    """The plan: a copy of the tiny campaigns where one also gives its chain as a DH table gets
    paper_dh.yaml and loop_dh.yaml per sensor, listed in its calibrated-files table; the other none."""
    shutil.copytree(tiny / "raw", tmp_path / "raw")
    metadata = files.read_yaml(tmp_path / "raw" / "tiny2" / "campaign.yaml")
    metadata["robot"]["dh"] = {"convention": "standard", "rows": [[0.0, 0.0, 0.1, 0.0]] * 7}  # only planned here
    files.write_yaml(tmp_path / "raw" / "tiny2" / "campaign.yaml", metadata)
    files.write_yaml(
        tmp_path / "config.yaml",
        {
            **files.read_yaml(tiny / "config.yaml"),
            "raw_dir": str(tmp_path / "raw"),
            "results_dir": str(tmp_path / "results"),
        },
    )
    tables = [str(tmp_path / "results" / name / "tables" / "calibrated_files.md") for name in ("tiny", "tiny2")]
    counts = planned_rules(tmp_path, *tables)
    assert counts.get("calibrated") == 2  # tiny: two sensors
    assert counts.get("calibrated_dh") == 1  # tiny2: one


def test_editing_the_robot_description_reruns_its_campaign_and_changes_its_audit_hash(tiny, tmp_path):
    """A URDF outside the campaign folder (campaign.yaml `robot/urdf`) is a declared input of the
    campaign's jobs and hashed with the campaign: editing it reruns them and changes the digest."""
    shutil.copytree(tiny / "raw" / "tiny", tmp_path / "raw" / "tiny")
    urdf = tmp_path / "robots" / "iiwa.urdf"
    urdf.parent.mkdir()
    shutil.copy(REPO / "data" / "robots" / "kuka_iiwa14.urdf", urdf)
    metadata = files.read_yaml(tmp_path / "raw" / "tiny" / "campaign.yaml")
    metadata["robot"]["urdf"] = "../../robots/iiwa.urdf"
    files.write_yaml(tmp_path / "raw" / "tiny" / "campaign.yaml", metadata)
    files.write_yaml(
        tmp_path / "config.yaml",
        {
            **files.read_yaml(tiny / "config.yaml"),
            "raw_dir": str(tmp_path / "raw"),
            "results_dir": str(tmp_path / "results"),
        },
    )
    target = str(tmp_path / "results" / "tiny" / "campaign" / "summary.json")
    assert run(tmp_path, "--", target).returncode == 0
    unchanged = run(tmp_path, "-n", "--", target)
    assert "Nothing to be done" in unchanged.stdout + unchanged.stderr
    folder_files = sorted((tmp_path / "raw" / "tiny").iterdir())
    robot = robot_model.robot_files(tmp_path / "raw" / "tiny")
    assert robot == [tmp_path / "raw" / "tiny" / "../../robots/iiwa.urdf"]
    before = audit.folder_digest(provenance.file_digests(folder_files + robot, True))
    urdf.write_text(urdf.read_text() + "\n<!-- edited -->\n")
    after = audit.folder_digest(provenance.file_digests(folder_files + robot, True))
    dry = run(tmp_path, "-n", "--", target)
    assert dry.returncode == 0 and "campaign_summary" in dry.stdout and "iiwa.urdf" in dry.stdout
    assert before != after


CHECK_SCRIPT = """<script>
window.addEventListener('load', () => {
  const broken = [...document.images].filter(i => !i.complete || i.naturalWidth === 0).length;
  const empty = [...document.querySelectorAll('h2')].filter(h => {
    let n = h.nextElementSibling, content = 0;
    while (n && n.tagName !== 'H2') { if (n.matches('table, figure, details, p, ul')) content++; n = n.nextElementSibling; }
    return content === 0;
  }).length;
  document.body.setAttribute('data-checked', `images=${document.images.length};broken=${broken};empty=${empty}`);
});
</script>"""


def _report_structure(page: str):
    """(section titles in order, PNG sizes (width, height) of every embedded image, sections with
    nothing under their title), read with the standard library's HTML parser."""
    import base64
    import struct
    from html.parser import HTMLParser

    class Reader(HTMLParser):
        def __init__(self):
            super().__init__()
            self.titles, self.sizes, self.content, self._in_h2 = [], [], [], False

        def handle_starttag(self, tag, attrs):
            if tag == "h2":
                self._in_h2 = True
                self.titles.append("")
                self.content.append(0)
            elif tag in ("table", "figure", "details", "p", "ul") and self.content:
                self.content[-1] += 1
            if tag == "img":
                data = base64.b64decode(dict(attrs)["src"].split(",", 1)[1])
                assert data[:8] == b"\x89PNG\r\n\x1a\n", "an embedded image is not a PNG"
                self.sizes.append(struct.unpack(">II", data[16:24]))

        def handle_endtag(self, tag):
            self._in_h2 = self._in_h2 and tag != "h2"

        def handle_data(self, data):
            if self._in_h2:
                self.titles[-1] += data

    reader = Reader()
    reader.feed(page)
    return reader.titles, reader.sizes, [t for t, n in zip(reader.titles, reader.content) if n == 0]


@pytest.mark.slow  # a real workflow run of minutes
def test_the_report_opens_with_verdicts_then_each_campaigns_certificate(tiny, tmp_path):
    """The page a metrologist opens: the overview of every campaign's verdict first, each campaign
    then opens with its certificate (the long tables fold away), every image is a real PNG and no
    section is empty; in headless Chromium (when the machine has it) every image renders."""
    if not (tiny / "results" / "report.html").exists():
        assert run(tiny).returncode == 0
    page = (tiny / "results" / "report.html").read_text(encoding="utf-8")
    titles, sizes, empty = _report_structure(page)
    assert titles[:3] == ["Overview", "tiny", "tiny2"] and not empty
    assert sizes and all(w > 100 and h > 100 for w, h in sizes)
    overview = page[page.index("<h2 id='overview'>") : page.index("<h2 id='tiny'>")]
    assert overview.count("<tr>") == 1 + 2 + 1  # header, tiny's two sensors, tiny2's one
    tiny_section = page[page.index("<h2 id='tiny'>") : page.index("<h2 id='tiny2'>")]
    assert tiny_section.index("Verdict per sensor") < tiny_section.index("<details>")
    serial = files.read_yaml(tiny / "raw" / "tiny" / "campaign.yaml")["robot"]["serial"]
    assert f"serial {serial} (7 joints)" in tiny_section and "U(Correction) (deg)" in tiny_section
    for name in ("tiny", "tiny2"):
        certificate = (tiny / "results" / name / "certificate.md").read_text(encoding="utf-8")
        assert (
            certificate.startswith(f"# Calibration certificate: {name}") and "## Valid for, and warnings" in certificate
        )
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("no Chromium on this machine: the page was checked without a browser")
    checked = tmp_path / "report.html"
    checked.write_text(page.replace("</body>", CHECK_SCRIPT + "</body>"), encoding="utf-8")
    dom = subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--virtual-time-budget=10000",
            "--dump-dom",
            checked.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    assert f'data-checked="images={len(sizes)};broken=0;empty=0"' in dom


def test_a_campaign_too_large_for_the_configured_memory_stops_at_its_first_job(tiny):
    """max_job_memory_gb below what the campaigns' jobs need: the campaign check refuses it with a
    message that names the campaign, its rows and the setting; no fit starts and no summary is left."""
    config = files.read_yaml(tiny / "config.yaml")
    files.write_yaml(
        tiny / "small_memory.yaml", {**config, "results_dir": str(tiny / "small_memory"), "max_job_memory_gb": 0.1}
    )
    result = run(tiny, config="small_memory.yaml")
    assert result.returncode != 0
    output = result.stdout + result.stderr
    assert "rows in its largest sensor" in output and "max_job_memory_gb" in output
    assert not list((tiny / "small_memory").glob("*/campaign/summary.json"))
    assert not list((tiny / "small_memory").glob("*/*/registration.json"))
