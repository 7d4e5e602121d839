"""The documentation stays true to the repository: docs/configuration.md is what the schema generates,
every relative link resolves, the reference pages' contents list every heading, the README keeps CI's test
command and its length, docs/cli.md names every subcommand and option, nothing points outside the
repository, and no tracked text file cites an issue number."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")), REPO / "benchmarks" / "README.md"]
# Written by another change at the same time as the links to it; a link to one of these is let
# through only while the file does not exist yet (once it exists, it is checked like any other).
PENDING = {REPO / "docs" / "cluster.md"}


def _generator():
    spec = importlib.util.spec_from_file_location("config_docs", REPO / "docs" / "config_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _schema() -> dict:
    return yaml.safe_load((REPO / "src" / "remaster" / "data" / "config.schema.yaml").read_text(encoding="utf-8"))


def test_configuration_page_is_what_the_schema_generates():
    page = REPO / "docs" / "configuration.md"
    assert page.read_text(encoding="utf-8") == _generator().markdown(_schema()), (
        "docs/configuration.md is stale or was edited by hand: run `python docs/config_docs.py --write`"
    )


def test_configuration_page_has_a_row_for_every_setting():
    text = (REPO / "docs" / "configuration.md").read_text(encoding="utf-8")
    for path in (
        "raw_dir",
        "fit/paper/samples",
        "fit/cross_check/max_rhat",
        "loop_closure/residual_gp/inducing",
        "priors/arm_class",
        "priors/industrial/joint_compliance_urad_per_Nm",
        "max_job_memory_gb",
    ):
        assert f"| `{path}` |" in text


def test_stray_key_detector_sees_a_description_cut_at_a_comma():
    schema = yaml.safe_load("properties:\n  a: {type: integer, description: Steps per chain, burn-in included.}\n")
    assert _generator().stray_keys(schema) == ["a: 'burn-in included.'"]
    assert _generator().stray_keys(yaml.safe_load("properties:\n  a: {type: integer, description: 'x, y'}\n")) == []


def test_schema_descriptions_are_whole():
    assert _generator().stray_keys(_schema()) == []


# --------------------------------------------------------------------------- links

LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    return {_slug(m) for m in re.findall(r"^#{1,6}\s+(.*?)\s*#*$", text, flags=re.M)}


def _broken_links(page: Path, root: Path = REPO) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    broken = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target):
            continue  # a web address
        path, _, anchor = target.partition("#")
        resolved = (page.parent / path).resolve() if path else page
        if resolved in PENDING and not resolved.exists():
            continue
        if not resolved.exists():
            broken.append(f"{target}: no such file")
        elif not resolved.is_relative_to(root):
            broken.append(f"{target}: outside the repository")
        elif anchor and resolved.suffix == ".md" and anchor not in _anchors(resolved):
            broken.append(f"{target}: no heading #{anchor}")
    return broken


def test_link_checker_sees_a_broken_link_and_a_missing_heading(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "# Two words\n[a](page.md#two-words) [b](gone.md) [c](#nothing) [d](https://x.org)\n```\n[e](in-code.md)\n```\n"
    )
    (tmp_path / "repo").mkdir()
    (tmp_path / "outside.md").write_text("")
    page.write_text(page.read_text() + "[f](outside.md)\n")
    assert _broken_links(page, root=tmp_path) == ["gone.md: no such file", "#nothing: no heading #nothing"]
    moved = tmp_path / "repo" / "page.md"
    moved.write_text("[f](../outside.md)\n")
    assert _broken_links(moved, root=tmp_path / "repo") == ["../outside.md: outside the repository"]


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(REPO)) for p in PAGES])
def test_relative_links_resolve(page):
    assert _broken_links(page) == []


def _contents_and_headings(text: str) -> tuple[list[str], list[str]]:
    """(the anchors the contents list links to, in order; the anchors of every `##` and `###` heading, in
    order). The contents list is the links `- [..](#..)` (indented for a `###`) before the first `##`."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    head = text.split("\n## ", 1)[0]
    contents = re.findall(r"^ *- \[[^\]]*\]\(#([^)\s]+)\)$", head, flags=re.M)
    return contents, [_slug(m) for m in re.findall(r"^#{2,3}\s+(.*?)\s*#*$", text, flags=re.M)]


def test_contents_checker_sees_a_missing_heading():
    page = "# T\n\n- [A](#a)\n  - [B c](#b-c)\n\n## A\n\n### B `c`\n\n## D\n"
    contents, headings = _contents_and_headings(page)
    assert contents == ["a", "b-c"] and headings == ["a", "b-c", "d"]


@pytest.mark.parametrize("name", ["methods.md", "validation.md", "planning.md"])
def test_the_contents_list_every_heading(name):
    """A reference page's contents list every `##` and `###` heading, in the page's order."""
    contents, headings = _contents_and_headings((REPO / "docs" / name).read_text(encoding="utf-8"))
    assert contents == headings


# --------------------------------------------------------------------------- issue numbers

# A text that cites the issue tracker (an issue's number, a sub-task's "n/5", "the issue" with its size
# or target) says nothing to a reader of the repository: it says what it means instead (the cyclic-error
# scenario, its full size). The pattern is split so that this file does not match it.
ISSUE_NUMBER = re.compile(r"issue[s]? ?[0-9]|[0-9]/5\b|[0-9]/6\b|\bthe issue" r"'s\b", re.I)


def test_the_issue_pattern_catches_a_citation_and_not_plain_text():
    cited = [
        "the cyclic case of issue" + " 4" + "/5",
        "Issue" + " 34's cyclic case",
        "the commit (1" + "/5) started from",
    ]
    cited += ["at the " + "issue's size", "issues" + " 2 and 3"]
    assert all(ISSUE_NUMBER.search(text) for text in cited)
    plain = ["a known issue with the tracker", "issue_scenario(seed=3)", "0.5 deg", "1/50 of the range", "4 of 5 seeds"]
    assert not any(ISSUE_NUMBER.search(text) for text in plain)


def test_no_tracked_text_file_names_an_issue_number():
    import subprocess

    try:
        tracked = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: no list of tracked files")
    found = []
    for name in filter(None, tracked.decode().split("\0")):
        path = REPO / name
        if not path.is_file():
            continue  # deleted in the working tree
        data = path.read_bytes()
        if b"\0" in data[:8192]:
            continue  # binary (Parquet, PNG)
        for number, line in enumerate(data.decode("utf-8", errors="replace").splitlines(), 1):
            if ISSUE_NUMBER.search(line):
                found.append(f"{name}:{number}: {line.strip()[:100]}")
    assert found == []


def test_nothing_points_outside_the_repository():
    for page in PAGES:
        assert "../shared" not in page.read_text(encoding="utf-8"), page
    sources = [*(REPO / "src").rglob("*.py"), *(REPO / "tests").rglob("*.py")]
    assert [str(p) for p in sources if "design" + ".md" in p.read_text(encoding="utf-8")] == []


# --------------------------------------------------------------------------- README and command line


def test_readme_is_short_and_keeps_ci_test_command():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 150
    lines = set(readme.splitlines())
    ci = [
        line.strip()
        for line in (REPO / ".ci" / "run").read_text(encoding="utf-8").splitlines()
        if line.strip().startswith("python3 -m venv") and "pytest" in line
    ]
    assert len(ci) == 1 and ci[0] in lines, "the README must show .ci/run's test command verbatim"
    assert "python3 -m venv .venv && .venv/bin/pip install -q -e . && .venv/bin/snakemake -j2" in lines


def test_cli_page_names_every_subcommand_and_option():
    from remaster import cli

    page = (REPO / "docs" / "cli.md").read_text(encoding="utf-8")
    parser = cli.parser()
    commands = next(a for a in parser._actions if a.choices and isinstance(a.choices, dict)).choices
    missing = [f"remaster {name}" for name in commands if f"remaster {name}" not in page]
    for name, command in commands.items():
        section = page.split(f"## remaster {name}", 1)[-1].split("\n## ", 1)[0]
        missing += [
            f"{name} {o}"
            for a in command._actions
            for o in a.option_strings
            if o.startswith("--") and o != "--help" and o not in section
        ]
    assert missing == []
