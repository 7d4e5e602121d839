"""Input files are data, never code: YAML tags that would build Python objects are refused with
a clear error and nothing runs; URDF entities are refused; no unsafe loader anywhere in the code."""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import pytest

from remaster import cli, files
from remaster.campaigns import folders
from remaster.campaigns.campaign import validate_metadata
from remaster.errors import InputError, KinematicsError
from remaster.robot import kinematics

from ..conftest import REPO, SNAKEMAKE
from .test_campaign import make_campaign, metadata


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


def billion_laughs(levels: int = 9) -> str:
    """A `date` of nested aliases: 9 levels of 9 repetitions, under 1 kB of text, expand to 9**9
    strings (a message quoting it used to take minutes and gigabytes)."""
    lines = ["date:", '  - &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"  - &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


def test_campaign_yaml_with_nested_aliases_is_refused_within_a_second(tmp_path):
    folder = make_campaign(tmp_path)
    path = folder / "campaign.yaml"
    text = path.read_text().replace("date: 2018-06-12\n", billion_laughs())
    path.write_text(text)
    assert len(text.encode()) < 1100
    start = time.perf_counter()
    with pytest.raises(InputError) as info:
        folders.read_campaign(folder, repo_root=REPO)
    assert time.perf_counter() - start < 1.0
    assert str(info.value).startswith(f"{path}: line 4: YAML alias *l0 refused")
    assert len(str(info.value)) < 300


def test_yaml_nested_beyond_the_parsers_depth_is_an_input_error(tmp_path):
    path = tmp_path / "campaign.yaml"
    path.write_text("date: " + "[" * 100_000 + "]" * 100_000 + "\n")
    with pytest.raises(InputError, match=r"campaign.yaml: YAML nested too deep to read"):
        files.read_yaml(path)


def test_a_huge_value_is_quoted_short_and_fast():
    """Whatever builds the value (here Python, sharing one list 9**9 times), a message quotes its start."""
    value = ["lol"] * 9
    for _ in range(8):
        value = [value] * 9
    start = time.perf_counter()
    with pytest.raises(InputError) as info:
        validate_metadata({**metadata(), "date": value}, source="campaign.yaml")
    assert time.perf_counter() - start < 1.0
    message = str(info.value)
    assert message.startswith("campaign.yaml: date: must be an ISO date YYYY-MM-DD, got [[[[") and "..." in message
    assert len(message) < 300


@pytest.mark.parametrize(
    ("where", "line", "key"),
    [("top", 10, "name"), ("sensor", 10, "sensors/laser_tracker/noise"), ("list item", 10, "robot/dh/rows/0/x")],
)
def test_a_duplicate_key_is_refused_with_file_key_and_line(tmp_path, where, line, key):
    folder = make_campaign(tmp_path)
    path = folder / "campaign.yaml"
    text = path.read_text()
    if where == "top":
        text += "name: demo\n"
    elif where == "sensor":
        text += "    noise: 3.0e-02\n"
    else:  # a key repeated in a mapping that is an item of a list
        text = text.replace("robot: {urdf:", "robot: {dh: {rows: [{x: 1, x: 2}]}, urdf:")
        line = 4
    path.write_text(text)
    with pytest.raises(InputError) as info:
        folders.read_campaign(folder, repo_root=REPO)
    assert str(info.value).startswith(f"{path}: {key}: line {line}: duplicate key (first on line ")
    assert info.value.file == str(path) and info.value.key == key


def test_a_scenario_with_a_duplicate_key_is_refused_by_the_cli(tmp_path, capsys):
    spec = (REPO / "data" / "simulation" / "kuka-twin.yaml").read_text() + "seed: 7\n"
    (tmp_path / "twice.yaml").write_text(spec)
    argv = ["simulate", str(tmp_path / "twice.yaml"), "--raw-dir", str(tmp_path / "raw")]
    assert cli.main([*argv, "--truth-dir", str(tmp_path / "truth")]) == 2
    error = capsys.readouterr().err
    line = len(spec.splitlines())
    assert f"twice.yaml: seed: line {line}: duplicate key (first on line " in error
    assert not (tmp_path / "raw").exists() and not (tmp_path / "truth").exists()


@pytest.mark.workflow
def test_config_with_a_python_tag_is_refused_by_the_workflow(tmp_path):
    """Snakemake reads config files with PyYAML's FullLoader, which has no constructor for
    object/apply (refused before remaster's Snakefile runs) and turns python/name into an object;
    remaster's Snakefile reads the file again with its own loader, which refuses the tag."""
    marker = tmp_path / "pwned"
    refused = "line 1: YAML tag 'tag:yaml.org,2002:python/name:os.system' refused"
    for kind, fragment in (("object/apply", "not valid JSON or YAML"), ("name", refused)):
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
    """One YAML reader, files.load_yaml, on a yaml.SafeLoader; nothing else parses YAML."""
    files_source = (REPO / "src" / "remaster" / "files.py").read_text()
    assert "class _PlainLoader(yaml.SafeLoader):" in files_source
    assert len(re.findall(r"_PlainLoader\(", files_source)) == 2  # its definition and load_yaml's one use
    sources = "".join(p.read_text() for p in (REPO / "src").rglob("*.py"))
    calls = re.findall(r"yaml\.(\w+)\(", sources)
    assert set(calls) <= {"safe_dump"}, calls
    assert set(re.findall(r"yaml\.\w*Loader\b", sources)) == {"yaml.SafeLoader"}
