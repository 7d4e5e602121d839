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
