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
# results: a stage's results read back (by the command line and the workflow's scripts); api.truth: a
# simulated campaign written to a temporary folder and read back as the workflow reads it; campaigns.bags:
# a ROS 2 bag, whose sqlite3 storage its reader (rosbags) opens by path; configuration: the workflow's
# folders (raw_dir, results_dir) checked and its campaigns listed (`workflow_run`)
FILE_ACCESS = {
    "files",
    "configuration",
    "campaigns.folders",
    "campaigns.robot_model",
    "campaigns.bags",
    "provenance",
    "results",
    "cli",
    "api.truth",
}


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
# read back, typed by the stages that wrote them, for the command line and the workflow; api: the Python
# interface, which runs the stages in-process). A module may
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
    "identity",
    "configuration",
}
STAGES = ("robot", "campaigns", "inference", "loop", "calibration", "evaluation", "comparing", "reporting", "planning")
INTERFACE = {"cli", "results", "api"}
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


# --------------------------------------------------------------------------- import cycles


def _import_cycles(imports: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of {module: the modules it imports}: each group of modules that import one
    another, directly or through others (a strongly connected component of more than one module,
    or a module that imports itself), sorted. Tarjan's algorithm."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for other in sorted(imports.get(module, ())):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            group = []
            while not group or group[-1] != module:
                group.append(stack.pop())
            if len(group) > 1 or module in imports.get(module, ()):
                cycles.append(sorted(group))

    for module in sorted(imports):
        if module not in index:
            visit(module)
    return sorted(cycles)


def test_no_import_cycle():
    """A module never imports, directly or through others, a module that imports it: not across
    packages, not inside one, not through an import inside a function (which only hides a cycle)."""
    modules = _modules()
    imports = {m: _imported_modules(path.read_text(encoding="utf-8"), m, modules) for m, path in modules.items()}
    assert _import_cycles(imports) == []
    # the check sees a cycle when there is one: through a late import inside a package, and longer ones
    pair = {"inference.gp.a", "inference.gp.b"}
    late = {
        "inference.gp.a": _imported_modules("from . import b\n", "inference.gp.a", pair),
        "inference.gp.b": _imported_modules("def f():\n    from .a import g\n", "inference.gp.b", pair),
    }
    assert _import_cycles(late) == [["inference.gp.a", "inference.gp.b"]]
    assert _import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}) == [["a", "b", "c"], ["e"]]
    assert _import_cycles({"a": {"b"}, "b": {"c"}, "d": {"a", "c"}}) == []


# --------------------------------------------------------------------------- light readers

# What a workflow job that only reads results (the tables, the figures, the report) must not
# import: each costs tenths of a second in every such job. The modules that compute keep these
# imports inside the functions that use them.
SOLVERS = ("scipy.optimize", "scipy.linalg", "scipy.stats", "emcee", "numba", "pinocchio")
READERS = ("tables", "figures", "campaign_figures", "comparison_figures", "report", "campaign_summary", "audit")


def _stage_modules(source: str) -> set[str]:
    """The package modules (dotted below remaster) that the stages `source` uses through
    `remaster.api.stages` load: `api.stages.<name>` (after `from remaster import api`), `stages.<name>`
    (after `from remaster.api import stages`) or `from remaster.api.stages import <name>`, each
    resolved by the stages' table (`api.stages.STAGES`)."""
    from remaster.api.stages import STAGES

    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute):
            held = node.value  # api.stages, or stages
            if isinstance(held, ast.Attribute) and held.attr == "stages" and isinstance(held.value, ast.Name):
                through_api = held.value.id == "api"
            else:
                through_api = isinstance(held, ast.Name) and held.id == "stages"
            if through_api:
                names.add(node.attr)
        elif isinstance(node, ast.ImportFrom) and node.module == "remaster.api.stages":
            names |= {a.name for a in node.names}
    unknown = names - set(STAGES)
    assert not unknown, f"not stages of remaster.api.stages: {sorted(unknown)}"
    return {STAGES[name][0] for name in names}


def test_the_import_detector_sees_the_stages_a_script_calls_through_the_api():
    source = (
        "from remaster import api\napi.stages.sample_posterior(1)\nf = api.stages.build_report\n"
        "from remaster.api import stages\nstages.close_loop()\nfrom remaster.api.stages import make_audit_record\n"
    )
    assert _stage_modules(source) == {"inference.fit", "reporting.report", "loop.loop_closure", "audit"}
    assert _stage_modules("from remaster import api\napi.calibrate(1)\n") == set()


def _library_imports(script: Path) -> list[str]:
    """The package modules a script loads: those it imports, and those of the stages it calls
    through `remaster.api.stages`."""
    source = script.read_text(encoding="utf-8")
    return sorted(_imported_modules(source, "", _modules()) | _stage_modules(source))


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
    # every reader's stage is seen (through remaster.api.stages), not only its direct imports
    assert {"reporting.report", "reporting.campaign_figures", "reporting.figures_comparison", "audit"} <= set(imports)
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


# --------------------------------------------------------------------------- benchmarks and tests


def _imports_from(source: str, package: str) -> list[str]:
    """The imports of `package` or its modules in `source`, as 'line N: module'."""
    found = []
    for node in ast.walk(ast.parse(source)):
        names = (
            [a.name for a in node.names]
            if isinstance(node, ast.Import)
            else [node.module or ""]
            if isinstance(node, ast.ImportFrom) and not node.level
            else []
        )
        found += [f"line {node.lineno}: {n}" for n in names if n == package or n.startswith(f"{package}.")]
    return found


def test_the_tests_calibrate_through_the_library_not_the_benchmarks_harness():
    """The tests run the pipeline's stages in-process through the library's Python interface
    (`remaster.api`, `remaster.api.truth`), never through the benchmarks' door onto it."""
    tests = sorted(Path(__file__).parent.rglob("*.py"))
    offenders = {
        str(p.relative_to(Path(__file__).parent)): hits
        for p in tests
        if (hits := _imports_from(p.read_text(encoding="utf-8"), "benchmarks.truth_claims"))
    }
    assert offenders == {}


def test_the_package_offers_its_interface_without_loading_it():
    """`import remaster` stays light (the command line's `--version`, the workflow's readers); its
    interface (`remaster.calibrate`, ...) is `remaster.api`'s, imported on first use."""
    import subprocess
    import sys

    code = (
        "import sys, remaster\n"
        "light = 'remaster.api' not in sys.modules\n"
        "assert remaster.calibrate is __import__('remaster.api').api.calibrate\n"
        "print(light, sorted(set(remaster.API) - set(dir(remaster.api))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "True []"


def test_no_benchmark_imports_from_the_tests():
    """What a benchmark shares with the tests lives in the library (e.g. `campaigns.arm_kinds`) or
    beside the benchmarks (benchmarks/truth_claims.py), never in tests/."""
    assert _imports_from("from tests.arm_kinds import x\nimport tests\nfrom testsuite import y\n", "tests") == [
        "line 1: tests.arm_kinds",
        "line 2: tests",
    ]
    benchmarks = sorted((Path(__file__).parents[1] / "benchmarks").glob("*.py"))
    assert benchmarks, "no benchmark found"
    offenders = {p.name: hits for p in benchmarks if (hits := _imports_from(p.read_text(encoding="utf-8"), "tests"))}
    assert offenders == {}


# --------------------------------------------------------------------------- the size of functions

MAX_LINES, MAX_PARAMETERS = 80, 8
# At most 5 functions of the library may be longer than MAX_LINES, each named here with why (a flat
# declaration that reads best whole, say); none is yet.
LONG_ALLOWED: set[str] = set()
# Longer now, to be split by their steps (the loop's selection, a GP computation, the robust
# design): each leaves this list when it is split; with LONG_ALLOWED never more than 5.
LONG_FOR_NOW = {
    "inference.gp.evidence_gain.log_evidence_gain",
    "loop.selection.select",
    "loop.tracker_noise.choose_noise",
    "planning.robust_design.robust_design",
}
# Compiled kernels take arrays, not objects (Numba compiles no dataclass): their arrays are their
# parameters.
MANY_PARAMETERS_ALLOWED = {
    "_kernels.metropolis_walk",
    "_kernels._points",
    "_kernels.points_linear",
    "_kernels._points_linear",
}
MANY_PARAMETERS_FOR_NOW = {  # as LONG_FOR_NOW: the samplers, the loop's selection, the robust design
    "inference.least_squares.least_squares_laplace",
    "inference.sampling.metropolis.metropolis_adaptive",
    "inference.sampling.independence.metropolis_independence",
    "inference.sampling.chains.run_emcee",
    "loop.fitted.fit_blocks",
    "loop.backward.backward_pass",
    "loop.backward.residual_backward_pass",
    "planning.robust_design.robust_design",
}


def _function_sizes(source: str, module: str = "") -> dict[str, tuple[int, int]]:
    """{module.qualified name: (lines from `def` to the last line, parameters)} of every function and
    method in `source`, nested ones included; the parameters count positional-only, keyword-only,
    *args and **kwargs, not a method's self or cls."""
    sizes = {}

    def visit(node, prefix: str, in_class: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = child.args
                named = [*a.posonlyargs, *a.args]
                bound = in_class and named and named[0].arg in ("self", "cls")
                count = len(named) - bound + len(a.kwonlyargs) + (a.vararg is not None) + (a.kwarg is not None)
                sizes[prefix + child.name] = (child.end_lineno - child.lineno + 1, count)
                visit(child, f"{prefix}{child.name}.", False)
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.", True)
            else:
                visit(child, prefix, in_class)

    visit(ast.parse(source), f"{module}." if module else "", False)
    return sizes


def test_the_size_counter_counts_lines_and_parameters():
    source = (
        "def f(a, b, /, c, *args, d, e=1, **kw):\n"
        '    """doc"""\n'
        "    def inner(x):\n"
        "        return x\n"
        "    return a\n"
        "\n\n"
        "class K:\n"
        "    def m(self, x, *, y):\n"
        "        pass\n"
    )
    assert _function_sizes(source, "mod") == {"mod.f": (5, 7), "mod.f.inner": (2, 1), "mod.K.m": (2, 2)}


def test_functions_are_short_and_take_few_parameters():
    sizes = {
        name: size
        for module, path in _modules().items()
        for name, size in _function_sizes(path.read_text(encoding="utf-8"), module).items()
    }
    long = {name for name, (lines, _) in sizes.items() if lines > MAX_LINES}
    many = {name for name, (_, count) in sizes.items() if count > MAX_PARAMETERS}
    assert len(LONG_ALLOWED | LONG_FOR_NOW) <= 5
    assert long - LONG_ALLOWED - LONG_FOR_NOW == set(), f"over {MAX_LINES} lines: split them by their steps"
    assert many - MANY_PARAMETERS_ALLOWED - MANY_PARAMETERS_FOR_NOW == set(), (
        f"over {MAX_PARAMETERS} parameters: a small frozen dataclass for those that travel together"
    )
    # a list names only what is still over the limit (a function split or gone leaves it)
    assert (LONG_ALLOWED | LONG_FOR_NOW) - long == set()
    assert (MANY_PARAMETERS_ALLOWED | MANY_PARAMETERS_FOR_NOW) - many == set()


# --------------------------------------------------------------------------- the size of modules

MAX_MODULE_LINES = 700
# The fitting core is cut by idea, one idea a module (as emcee's moves/): a module longer than this
# holds more than one.
CUT_BY_IDEA = ("inference", "loop")


def test_the_fitting_core_has_no_module_over_700_lines():
    long = {
        name: lines
        for name, path in _modules().items()
        if name.split(".")[0] in CUT_BY_IDEA
        and (lines := len(path.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert long == {}, f"over {MAX_MODULE_LINES} lines: cut them by what their code does"
