"""What made a result, identified by content: digests of files, of the package's code, and the git
commit of the checkout (`remaster.audit` assembles them into the audit record)."""

from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path


def file_digests(paths, relative_to_parent: bool = False) -> dict[str, str]:
    """SHA-256 (hex) of each file, keyed by its path (or by its name within its folder)."""
    out = {}
    for path in map(Path, paths):
        key = path.name if relative_to_parent else str(path)
        out[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def package_digests() -> dict[str, str]:
    """SHA-256 of every source file of the installed remaster package, keyed by its path in it:
    the code that made a result, identified by content."""
    root = Path(__file__).resolve().parent  # this module lies at the package's top
    files = sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts)
    return {str(p.relative_to(root)): digest for p, digest in zip(files, file_digests(files).values())}


def git_commit(repo_root: str | Path = ".") -> dict | None:
    """{'commit', 'dirty'} of the git checkout at repo_root, None outside one (or without git)."""
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo_root, capture_output=True, text=True, timeout=30)
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=repo_root,
            capture_output=True,
            text=True,
            timeout=30,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    if commit.returncode != 0:
        return None
    return {"commit": commit.stdout.strip(), "dirty": bool(status.stdout.strip())}
