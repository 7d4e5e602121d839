"""The audit trail: what every result of a run was made from.

For each campaign, the SHA-256 of each of its files, of the robot description it refers to (a
URDF outside the folder), and of the whole (over the sorted file names and their digests, so
renaming or editing any file changes it), the configuration as used (and its digest), the code by
content (a digest of the package's source files, and the git commit when there is one), the seed,
and the SHA-256 of every result file.
A result can so be traced to exactly the data, settings and code that made it.
"""

from __future__ import annotations

import hashlib
import json
import platform

from . import __version__


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def folder_digest(file_digests: dict[str, str]) -> str:
    """One digest of a set of files: SHA-256 over 'name digest' lines in name order."""
    lines = "".join(f"{name} {digest}\n" for name, digest in sorted(file_digests.items()))
    return sha256(lines.encode("utf-8"))


def config_digest(config: dict) -> str:
    """SHA-256 of the configuration as canonical JSON (sorted keys)."""
    return sha256(json.dumps(config, sort_keys=True, separators=(",", ":")).encode("utf-8"))


def audit_record(
    campaigns: dict[str, dict[str, str]],
    results: dict[str, dict[str, str]],
    config: dict,
    code: dict[str, str] | None = None,
    git: dict | None = None,
    outside: dict[str, list[str]] | None = None,
) -> dict:
    """campaigns: campaign -> {file name: SHA-256} (its folder's files and the robot description
    it refers to); results: campaign -> {result path: SHA-256}; config: the workflow configuration
    as used; code: {package file: SHA-256} of the remaster package that ran; git: {'commit',
    'dirty'} of the checkout, if any; outside: campaign -> its input files that resolve outside its
    folder (`folders.outside_inputs`). JSON-ready."""
    return {
        "remaster_version": __version__,
        "code": {"package_sha256": folder_digest(code or {}), "package_files": len(code or {}), "git": git},
        "python": platform.python_version(),
        "seed": config.get("seed"),
        "config_sha256": config_digest(config),
        "config": config,
        "campaigns": {
            name: {
                "content_sha256": folder_digest(files),
                "files": dict(sorted(files.items())),
                "results": dict(sorted(results.get(name, {}).items())),
                "inputs_outside_the_folder": list((outside or {}).get(name, [])),
            }
            for name, files in sorted(campaigns.items())
        },
    }
