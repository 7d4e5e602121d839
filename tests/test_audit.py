"""The audit trail changes with any byte of a campaign and records the run's settings."""

import remaster
from remaster import audit, provenance


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
