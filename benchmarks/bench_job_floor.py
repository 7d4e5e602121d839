"""The main job's floor: `snakemake -j2` on the bundled campaigns with every job's work taken out.

Run from the repository root: python benchmarks/bench_job_floor.py
It copies the workflow into a temporary folder and replaces each script twice over:
- "bare": the script only creates its output files (what Snakemake itself costs per job: planning,
  starting Python, its script preamble, checking outputs);
- "imports": the script's own top-level imports, then its outputs (what each job pays before it
  does any work: pandas, pyarrow, numpy, matplotlib, the library).
Both run the real DAG (the same jobs as the main job) from empty results; the third line is the main
job itself, for comparison. If the floor with imports is above a wall-time target, no amount of
faster computing meets that target with this set of jobs and these libraries; the main job minus
that floor is what the jobs' work itself takes.
"""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TOUCH_OUTPUTS = (
    "from pathlib import Path as _Path\n"
    "for _file in snakemake.output:  # noqa: F821\n"
    "    _Path(_file).parent.mkdir(parents=True, exist_ok=True)\n"
    "    _Path(_file).touch()\n"
)


def top_level_imports(script: Path) -> str:
    """The import statements at a script's top level, as source."""
    source = script.read_text(encoding="utf-8")
    nodes = [n for n in ast.parse(source).body if isinstance(n, (ast.Import, ast.ImportFrom))]
    return "".join(ast.get_source_segment(source, n) + "\n" for n in nodes)


def stub_workflow(folder: Path, keep_imports: bool) -> Path:
    """A copy of the workflow in `folder` whose scripts do no work; data/ is linked, not copied."""
    folder.mkdir(parents=True)
    shutil.copy(REPO / "Snakefile", folder / "Snakefile")
    shutil.copy(REPO / "config.yaml", folder / "config.yaml")
    shutil.copytree(REPO / "workflow", folder / "workflow")
    if (REPO / "profiles").is_dir():
        shutil.copytree(REPO / "profiles", folder / "profiles")
    (folder / "data").symlink_to(REPO / "data")
    for script in (folder / "workflow" / "scripts").glob("*.py"):
        imports = top_level_imports(script) if keep_imports else ""
        script.write_text(imports + TOUCH_OUTPUTS, encoding="utf-8")
    return folder


def timed_run(workdir: Path, results: Path) -> tuple[float, int]:
    """Wall seconds of `snakemake -j2` in `workdir` into the empty folder `results`, and its job count."""
    command = [sys.executable, "-m", "snakemake", "-j2", "--config", f"results_dir={results}"]
    started = time.perf_counter()
    run = subprocess.run(command, cwd=workdir, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if run.returncode != 0:
        sys.exit(f"snakemake failed in {workdir}:\n{run.stderr[-3000:]}")
    return wall, (run.stdout + run.stderr).count("Finished jobid")


def main() -> None:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, keep_imports in (("bare", False), ("imports", True)):
            workdir = stub_workflow(tmp / name, keep_imports)
            rows.append((f"no work, {name}", *timed_run(workdir, tmp / name / "results")))
        rows.append(("the main job", *timed_run(REPO, tmp / "main_results")))
    print("| run | jobs | wall s | wall s per job |\n|---|---|---|---|")
    for name, wall, jobs in rows:
        print(f"| {name} | {jobs} | {wall:.0f} | {wall / max(jobs, 1):.2f} |")
    (_, bare, _), (_, imports, _), (_, main_job, _) = rows
    print(
        f"the jobs' work alone, both cores busy throughout: about {main_job - imports:.0f} s "
        f"(+ {bare:.0f} s of Snakemake if importing cost nothing)"
    )


if __name__ == "__main__":
    main()
