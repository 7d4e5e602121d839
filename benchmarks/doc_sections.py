"""A benchmark's measured numbers into the page that states them: the text between a pair of
markers (`<!-- name:begin -->`, `<!-- name:end -->`) is replaced by what the benchmark wrote, so no
number on that page is typed by hand."""

from __future__ import annotations

from pathlib import Path


def markers(name: str) -> tuple[str, str]:
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def write_section(page: Path, name: str, text: str) -> bool:
    """Replace the section `name` of `page` by text; False (page unchanged) when it has no such markers."""
    begin, end = markers(name)
    content = page.read_text(encoding="utf-8")
    if begin not in content or end not in content:
        return False
    head, rest = content.split(begin, 1)
    page.write_text(f"{head}{begin}\n{text}\n{end}{rest.split(end, 1)[1]}", encoding="utf-8")
    return True


def publish(results: Path, name: str, record: dict, text: str, page: Path) -> None:
    """A benchmark's record: results/<name>.json, its table as results/<name>.md and in `page`'s
    section bench_<name> (`write_section`), and on the terminal."""
    import json

    results.mkdir(exist_ok=True)
    (results / f"{name}.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    (results / f"{name}.md").write_text(text + "\n", encoding="utf-8")
    write_section(page, f"bench_{name}", text)
    print(text)
