"""The library keeps file access in one place: only remaster.io (and the command line, which
parses path arguments) may touch the filesystem."""

from __future__ import annotations

import ast
from pathlib import Path

import remaster

FILE_MODULES = {"pathlib", "shutil", "tempfile", "glob", "os"}
ALLOWED = {"io.py", "cli.py"}


def _file_access(source: str) -> list[str]:
    """Imports of filesystem modules and calls of open() in `source`, as 'line N: what'."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [f"line {node.lineno}: import {a.name}" for a in node.names if a.name.split(".")[0] in FILE_MODULES]
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in FILE_MODULES:
            names = {a.name for a in node.names}
            if names - {"PurePosixPath", "PurePath", "PureWindowsPath"}:  # pure paths never touch the disk
                found.append(f"line {node.lineno}: from {node.module} import {', '.join(sorted(names))}")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "open":
            found.append(f"line {node.lineno}: open()")
    return found


def test_file_access_detector_sees_imports_and_open():
    assert _file_access("import shutil\nfrom pathlib import Path\nopen('x')\n") == [
        "line 1: import shutil", "line 2: from pathlib import Path", "line 3: open()"]
    assert _file_access("from pathlib import PurePosixPath\nimport io as _s\n") == []


def test_only_io_and_cli_touch_files():
    package = Path(remaster.__file__).parent
    offenders = {p.name: hits for p in sorted(package.glob("*.py")) if p.name not in ALLOWED
                 and (hits := _file_access(p.read_text(encoding="utf-8")))}
    assert offenders == {}
