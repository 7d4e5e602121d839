"""The audit trail changes with any byte of a campaign and records the run's settings."""

import remaster
from remaster import audit, provenance

from .conftest import REPO


def test_folder_digest_sees_every_file_and_name():
    files = {"campaign.yaml": audit.sha256(b"name: a"), "lt.parquet": audit.sha256(b"123")}
    digest = audit.folder_digest(files)
    assert digest == audit.folder_digest(dict(reversed(list(files.items()))))  # order-free
    assert digest != audit.folder_digest({**files, "lt.parquet": audit.sha256(b"124")})
    assert digest != audit.folder_digest({"campaign.yaml": files["campaign.yaml"], "mc.parquet": files["lt.parquet"]})


def test_record_holds_config_version_seed_and_results():
    config = {"seed": 7, "fit": {"paper": {"samples": 10}}}
    record = audit.audit_record({"c1": {"a": "00"}}, {"c1": {"results/c1/x.csv": "11"}}, config)
    assert record["seed"] == 7 and record["config"] == config
    assert record["config_sha256"] == audit.config_digest({"fit": {"paper": {"samples": 10}}, "seed": 7})
    assert record["campaigns"]["c1"]["results"] == {"results/c1/x.csv": "11"}
    assert record["remaster_version"]


def test_the_code_is_identified_by_the_content_of_the_package_that_ran(tmp_path):
    """Every source file of the package is hashed: the record's package digest is theirs, and
    changing one file's digest changes it; the version is the package's own; outside a git
    checkout there is no commit to record."""
    code = provenance.package_digests()
    assert {"audit.py", "files.py", "noise.py"} <= set(code) and all(len(d) == 64 for d in code.values())
    record = audit.audit_record({}, {}, {}, code, {"commit": "abc", "dirty": False})
    assert record["code"]["package_sha256"] == audit.folder_digest(code)
    assert record["code"]["package_files"] == len(code) and record["code"]["git"]["commit"] == "abc"
    assert (
        audit.audit_record({}, {}, {}, {**code, "files.py": "0" * 64})["code"]["package_sha256"]
        != record["code"]["package_sha256"]
    )
    assert record["remaster_version"] == remaster.__version__
    assert provenance.git_commit(tmp_path) is None


def test_inputs_from_outside_the_campaign_folder_are_listed_in_the_audit_and_the_certificate(tmp_path):
    """A shared URDF named by a path outside the folder and a Parquet file that is a symbolic link
    to a file elsewhere are read, and named: in the campaign's summary (whose heading line the
    certificate prints) and the audit record; a campaign whose files all live in it names none."""
    import shutil

    from remaster import audit
    from remaster.campaigns import folders

    source = REPO / "data" / "raw" / "jacobi-ur5-gts3800"
    inside = tmp_path / "jacobi-ur5-gts3800"
    shutil.copytree(source, inside)
    assert folders.outside_inputs(inside, REPO) == []
    elsewhere = tmp_path / "store"
    elsewhere.mkdir()
    (inside / "laser_tracker.parquet").rename(elsewhere / "tracker.parquet")
    (inside / "laser_tracker.parquet").symlink_to(elsewhere / "tracker.parquet")
    outside = folders.outside_inputs(inside, REPO)
    assert outside == [f"laser_tracker.parquet -> {(elsewhere / 'tracker.parquet').resolve()}"]
    summary = folders.summarize_folder(inside)
    assert summary["inputs_outside_the_folder"] == outside
    record = audit.audit_record({"c": {}}, {}, {}, outside={"c": outside})
    assert record["campaigns"]["c"]["inputs_outside_the_folder"] == outside
    # the bundled twin reads the shared iiwa URDF from data/robots/
    twin = folders.outside_inputs(REPO / "data" / "raw" / "kuka-twin", REPO)
    assert twin == [f"kuka_iiwa14.urdf -> {(REPO / 'data' / 'robots' / 'kuka_iiwa14.urdf').resolve()}"]
