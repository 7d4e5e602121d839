"""The audit trail changes with any byte of a campaign and records the run's settings."""

from remaster import audit


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
