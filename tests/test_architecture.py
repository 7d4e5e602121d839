"""The library keeps file access in one place: only remaster.io (and the command line, which
parses path arguments) may touch the filesystem; and its modules import along the pipeline's
direction only (a layer map)."""

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


# --------------------------------------------------------------------------- layering

# The pipeline's direction, bottom to top: a module may import its own layer and those below,
# never a later stage (a new module must be placed here, or the test says so).
LAYERS = {
    "foundation": {"__init__", "errors", "spatial", "units", "labels", "_kernels", "seeding", "diagnostics", "noise",
                   "audit"},
    "robot": {"kinematics", "gravity", "ik", "registration", "priors", "planning"},
    "campaigns": {"campaign", "importer", "simulation", "scenario"},
    "inference": {"model", "identifiability", "samplers", "metrics", "fit", "blocks", "evidence", "residual_gp",
                  "discrepancy"},
    "loop": {"closure", "loop_closure"},
    "analysis": {"prediction", "workspace", "accuracy", "transfer", "comparison", "calibrated", "dh_table",
                 "compensation"},
    "reporting": {"tables", "figures", "figures_accuracy", "figures_comparison", "figures_loop", "report"},
    "interface": {"io", "cli"},  # the edges: files (read and written for every stage) and the command line
}
LAYER_OF = {module: rank for rank, modules in enumerate(LAYERS.values()) for module in modules}
LAYER_NAMES = list(LAYERS)


def _imported_modules(source: str, modules: set[str]) -> set[str]:
    """The package modules `source` imports (relative or absolute, anywhere in the file)."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level == 1 or module == "remaster" or module.startswith("remaster."):
                name = module.removeprefix("remaster").lstrip(".").split(".")[0]
                found |= {name} if name else {a.name for a in node.names if a.name in modules}
        elif isinstance(node, ast.Import):
            found |= {a.name.split(".")[1] for a in node.names if a.name.startswith("remaster.")}
    return found & modules


def test_the_import_detector_sees_relative_absolute_and_late_imports():
    modules = {"fit", "tables", "model"}
    source = "from . import fit\nfrom .tables import x\ndef f():\n    from remaster.model import y\nimport numpy\n"
    assert _imported_modules(source, modules) == {"fit", "tables", "model"}


def test_no_module_imports_a_later_stage():
    package = Path(remaster.__file__).parent
    modules = {p.stem for p in package.glob("*.py")}
    assert modules - set(LAYER_OF) == set(), "place new modules in LAYERS"
    upward = {f"{m} ({layer}) imports {d} ({LAYER_NAMES[LAYER_OF[d]]})"
              for m in sorted(modules) for layer in [LAYER_NAMES[LAYER_OF[m]]]
              for d in _imported_modules((package / f"{m}.py").read_text(encoding="utf-8"), modules)
              if LAYER_OF[d] > LAYER_OF[m]}
    assert upward == set()


# --------------------------------------------------------------------------- light readers

# What a workflow job that only reads results (a table, a figure, the report) must not import:
# each costs tenths of a second in every one of some 200 jobs of the main job. The modules that
# compute keep these imports inside the functions that use them.
SOLVERS = ("scipy.optimize", "scipy.linalg", "scipy.stats", "emcee", "numba", "pinocchio")
READERS = ("table_", "figure_", "comparison_figure", "comparison_table", "comparison_transfer_figure", "report",
           "posterior_summary", "remastering", "campaign_summary", "audit")


def _library_imports(script: Path) -> list[str]:
    return sorted(_imported_modules(script.read_text(encoding="utf-8"),
                                    {p.stem for p in Path(remaster.__file__).parent.glob("*.py")}))


def test_jobs_that_only_read_results_import_no_solver():
    import subprocess
    import sys

    scripts = [p for p in sorted((Path(__file__).parents[1] / "workflow" / "scripts").glob("*.py"))
               if p.stem.startswith(READERS)]
    assert len(scripts) >= 15
    imports = sorted({m for p in scripts for m in _library_imports(p)})
    code = ("import sys\n" + "".join(f"import remaster.{m}\n" for m in imports)
            + f"print(','.join(m for m in {SOLVERS!r} if m in sys.modules))")
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert loaded == "", f"importing {imports} loads {loaded}"
    # the check itself sees a solver when one is imported
    seen = subprocess.run([sys.executable, "-c", "import sys, remaster.evidence, scipy.optimize\n"
                           f"print(','.join(m for m in {SOLVERS!r} if m in sys.modules))"],
                          capture_output=True, text=True, check=True).stdout.strip()
    assert "scipy.optimize" in seen
