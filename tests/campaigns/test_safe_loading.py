"""Input files are data, never code: YAML tags that would build Python objects are refused with
a clear error and nothing runs; URDF entities are refused; no unsafe loader anywhere in the code."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from remaster import cli
from remaster.campaigns import folders
from remaster.errors import InputError, KinematicsError
from remaster.robot import kinematics

from ..conftest import REPO
from .test_campaign import make_campaign

SNAKEMAKE = [sys.executable, "-m", "snakemake"]


def payloads(marker: Path) -> dict[str, str]:
    """YAML values that, with an unsafe loader, would create `marker` (or import a callable)."""
    return {
        "object/apply": f'!!python/object/apply:os.system ["touch {marker}"]',
        "object/new": f'!!python/object/new:subprocess.check_call [["touch", "{marker}"]]',
        "name": "!!python/name:os.system",
        "module": "!!python/module:os",
    }


@pytest.mark.parametrize("kind", ["object/apply", "object/new", "name", "module"])
def test_campaign_yaml_with_a_python_tag_is_refused_and_nothing_runs(tmp_path, kind):
    folder = make_campaign(tmp_path)
    marker = tmp_path / "pwned"
    text = (folder / "campaign.yaml").read_text()
    lines = text.splitlines()
    line = next(i for i, text_line in enumerate(lines) if text_line.startswith("description:"))
    lines[line] = f"description: {payloads(marker)[kind]}"
    (folder / "campaign.yaml").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as info:
        folders.read_campaign(folder, repo_root=REPO)
    message = str(info.value)
    assert message.startswith(f"{folder / 'campaign.yaml'}: line {line + 1}: YAML tag 'tag:yaml.org,2002:python/")
    assert "refused" in message and "nothing was executed" in message
    assert not marker.exists()


def test_scenario_with_a_python_tag_is_refused_by_the_cli(tmp_path, capsys):
    marker = tmp_path / "pwned"
    spec = (REPO / "data" / "simulation" / "kuka-twin.yaml").read_text()
    spec = spec.replace("seed: 20180612", f"seed: {payloads(marker)['object/apply']}")
    (tmp_path / "evil.yaml").write_text(spec)
    status = cli.main(
        [
            "simulate",
            str(tmp_path / "evil.yaml"),
            "--raw-dir",
            str(tmp_path / "raw"),
            "--truth-dir",
            str(tmp_path / "truth"),
        ]
    )
    assert status == 2
    error = capsys.readouterr().err
    assert "evil.yaml: line" in error and "python/object/apply:os.system' refused" in error
    assert not marker.exists() and not (tmp_path / "raw").exists() and not (tmp_path / "truth").exists()


@pytest.mark.workflow
def test_config_with_a_python_tag_is_refused_by_the_workflow(tmp_path):
    """Snakemake reads config files with PyYAML's FullLoader, which has no constructor for
    object/apply (refused before remaster's Snakefile runs) and turns python/name into an object
    that the schema then refuses."""
    marker = tmp_path / "pwned"
    for kind, fragment in (("object/apply", "not valid JSON or YAML"), ("name", "is not of type 'string'")):
        config = tmp_path / f"config-{kind.replace('/', '-')}.yaml"
        config.write_text(f"results_dir: {payloads(marker)[kind]}\n")
        result = subprocess.run(
            SNAKEMAKE + ["-n", "--configfile", str(config)], cwd=REPO, capture_output=True, text=True, timeout=300
        )
        assert result.returncode != 0 and fragment in result.stdout + result.stderr
        assert not marker.exists()


BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE robot [
  <!ENTITY a "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa">
  <!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
  <!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">
]>
<robot name="&c;"><link name="base"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="tool"/></joint></robot>"""


def test_urdf_with_entities_is_refused(tmp_path):
    with pytest.raises(KinematicsError, match=r"^robot.urdf: declares XML entities"):
        kinematics.chain_from_urdf(BILLION_LAUGHS, source="robot.urdf")


# --------------------------------------------------------------------------- the code itself

UNSAFE = {
    "pickle": r"\bc?pickle\b|read_pickle|to_pickle|allow_pickle\s*=\s*True",
    "eval/exec": r"(?<![\w.])(eval|exec)\s*\(",
    "unsafe YAML": (
        r"yaml\.load\s*\((?![^)]*SafeLoader)|yaml\.unsafe_load|yaml\.full_load"
        r"|Loader\s*=\s*yaml\.(Unsafe|Full)?Loader\b"
    ),
    "other deserialisers": r"\bmarshal\.loads?\b|\bshelve\b|\bdill\b|\bjoblib\.load\b|\btorch\.load\b",
    "shell": r"shell\s*=\s*True|os\.system\s*\(",
}


def source_files():
    files = sorted((REPO / "src").rglob("*.py")) + sorted((REPO / "workflow").rglob("*.py"))
    files += sorted((REPO / "workflow").rglob("*.smk")) + [REPO / "Snakefile"]
    return [f for f in files if "__pycache__" not in f.parts]


def test_no_pickle_eval_exec_or_unsafe_yaml_in_the_code():
    files = source_files()
    assert any(f.name == "files.py" for f in files)
    found = []
    for path in files:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            for what, pattern in UNSAFE.items():
                if re.search(pattern, line):
                    found.append(f"{path.relative_to(REPO)}:{number}: {what}: {line.strip()}")
    assert found == []


def test_yaml_is_read_with_safe_load_only():
    files_source = (REPO / "src" / "remaster" / "files.py").read_text()
    assert "yaml.safe_load(" in files_source
    calls = re.findall(r"yaml\.(\w+)\(", "".join(p.read_text() for p in (REPO / "src").rglob("*.py")))
    assert set(calls) <= {"safe_load", "safe_dump"}, calls
