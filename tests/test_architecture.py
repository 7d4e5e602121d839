"""The library keeps file access in a few named places: only the modules of FILE_ACCESS (and the
command line, which parses path arguments) may touch the filesystem; and its modules import along
the pipeline's direction only (a layer map)."""

from __future__ import annotations

import ast
from pathlib import Path

import remaster

FILE_MODULES = {"pathlib", "shutil", "tempfile", "glob", "os"}
# files: plain files (YAML, JSON, CSV, Parquet, figures, logs); campaigns.folders: campaign folders;
# campaigns.robot_model: the robot description a campaign names; provenance: digests of files and code;
# results: a stage's results read back (by the command line and the workflow's scripts)
FILE_ACCESS = {"files", "campaigns.folders", "campaigns.robot_model", "provenance", "results", "cli"}


def _file_access(source: str) -> list[str]:
    """Imports of filesystem modules and calls of open() in `source`, as 'line N: what'."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [
                f"line {node.lineno}: import {a.name}" for a in node.names if a.name.split(".")[0] in FILE_MODULES
            ]
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in FILE_MODULES:
            names = {a.name for a in node.names}
            if names - {"PurePosixPath", "PurePath", "PureWindowsPath"}:  # pure paths never touch the disk
                found.append(f"line {node.lineno}: from {node.module} import {', '.join(sorted(names))}")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "open":
            found.append(f"line {node.lineno}: open()")
    return found


def test_file_access_detector_sees_imports_and_open():
    assert _file_access("import shutil\nfrom pathlib import Path\nopen('x')\n") == [
        "line 1: import shutil",
        "line 2: from pathlib import Path",
        "line 3: open()",
    ]
    assert _file_access("from pathlib import PurePosixPath\nimport io as _s\n") == []


def _modules() -> dict[str, Path]:
    """{dotted name below remaster (e.g. 'inference.fit'): file} of every module of the package."""
    package = Path(remaster.__file__).parent
    return {
        ".".join(p.relative_to(package).with_suffix("").parts): p
        for p in sorted(package.rglob("*.py"))
        if "__pycache__" not in p.parts
    }


def test_only_the_file_modules_and_cli_touch_files():
    modules = _modules()
    assert FILE_ACCESS <= set(modules), "a module of FILE_ACCESS is gone: update the list"
    offenders = {
        name: hits
        for name, path in modules.items()
        if name not in FILE_ACCESS and (hits := _file_access(path.read_text(encoding="utf-8")))
    }
    assert offenders == {}


# --------------------------------------------------------------------------- layering

# The pipeline's direction, bottom to top: the foundation (modules beside the packages that any
# stage may use, among them files, layout and provenance: the files every stage reads and writes),
# the sub-packages in the workflow's order, and the edge (cli: the command line; results: the results
# read back, typed by the stages that wrote them, for the command line and the workflow). A module may
# import its own layer and those below, never a later stage; a new top-level module must be placed
# here, or the test says so.
FOUNDATION = {
    "__init__",
    "errors",
    "spatial",
    "units",
    "labels",
    "_kernels",
    "seeding",
    "diagnostics",
    "noise",
    "audit",
    "files",
    "layout",
    "provenance",
    "stage_inputs",
}
STAGES = ("robot", "campaigns", "inference", "loop", "analysis", "reporting")
INTERFACE = {"cli", "results"}
LAYER_NAMES = ["foundation", *STAGES, "interface"]


def _layer(module: str) -> int:
    top = module.split(".")[0]
    if top in STAGES:
        return 1 + STAGES.index(top)
    return 0 if top in FOUNDATION else len(LAYER_NAMES) - 1 if top in INTERFACE else -1


def _imported_modules(source: str, here: str, modules) -> set[str]:
    """The package modules (dotted below remaster) that `source`, the module `here` ('' for a
    script outside the package), imports: relative or absolute, anywhere in the file."""
    package = here.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                base = package[: len(package) - (node.level - 1)] + ([module] if module else [])
            elif module == "remaster" or module.startswith("remaster."):
                base = module.split(".")[1:]
            else:
                continue
            name = ".".join(base)
            found |= {name} if name in modules else {f"{name}.{a.name}".lstrip(".") for a in node.names}
        elif isinstance(node, ast.Import):
            found |= {a.name.removeprefix("remaster.") for a in node.names if a.name.startswith("remaster.")}
    return found & set(modules)


def test_the_import_detector_sees_relative_absolute_and_late_imports():
    modules = {"inference.fit", "reporting.tables", "inference.model", "units"}
    source = (
        "from . import fit\nfrom ..reporting.tables import x\nfrom .. import units\ndef f():\n"
        "    from remaster.inference.model import y\nimport numpy\n"
    )
    assert _imported_modules(source, "inference.evidence", modules) == modules


def test_no_module_imports_a_later_stage():
    modules = _modules()
    unplaced = {m for m in modules if _layer(m) < 0}
    assert unplaced == set(), "place new top-level modules in FOUNDATION or INTERFACE"
    upward = {
        f"{m} ({LAYER_NAMES[_layer(m)]}) imports {d} ({LAYER_NAMES[_layer(d)]})"
        for m, path in modules.items()
        for d in _imported_modules(path.read_text(encoding="utf-8"), m, modules)
        if _layer(d) > _layer(m)
    }
    assert upward == set()
    # the check sees an upward import when there is one
    assert _layer("reporting.tables") > _layer("inference.fit") and _imported_modules(
        "from ..reporting import tables\n", "inference.fit", modules
    ) == {"reporting.tables"}


# --------------------------------------------------------------------------- light readers

# What a workflow job that only reads results (the tables, the figures, the report) must not
# import: each costs tenths of a second in every such job. The modules that compute keep these
# imports inside the functions that use them.
SOLVERS = ("scipy.optimize", "scipy.linalg", "scipy.stats", "emcee", "numba", "pinocchio")
READERS = ("tables", "figures", "campaign_figures", "comparison_figures", "report", "campaign_summary", "audit")


def _library_imports(script: Path) -> list[str]:
    return sorted(_imported_modules(script.read_text(encoding="utf-8"), "", _modules()))


def test_jobs_that_only_read_results_import_no_solver():
    import subprocess
    import sys

    scripts = [
        p for p in sorted((Path(__file__).parents[1] / "workflow" / "scripts").glob("*.py")) if p.stem in READERS
    ]
    assert len(scripts) == len(READERS)
    imports = sorted({m for p in scripts for m in _library_imports(p)})
    code = (
        "import sys\n"
        + "".join(f"import remaster.{m}\n" for m in imports)
        + f"print(','.join(m for m in {SOLVERS!r} if m in sys.modules))"
    )
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert loaded == "", f"importing {imports} loads {loaded}"
    # the check itself sees a solver when one is imported
    seen = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, remaster.inference.evidence, scipy.optimize\n"
            f"print(','.join(m for m in {SOLVERS!r} if m in sys.modules))",
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert "scipy.optimize" in seen
