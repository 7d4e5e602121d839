"""The main job's wall time against an earlier commit's, side by side, and the test command's time.

Both checkouts run `snakemake -j2` from an empty results folder on the same campaigns (by default
the four simulated campaigns that both have), alternately (base, this, base, this, ...), so that a
machine whose speed drifts during the session affects both alike. Each run imports its own
checkout's library (PYTHONPATH), with the one environment this script runs in. The numbers go to
benchmarks/results/main_job.json and into benchmarks/README.md between the bench_main_job markers.

With --keep DIR, each checkout's last results stay in DIR/base and DIR/this, for comparing them
file by file. With --tests, the README's test command is timed in both checkouts as well, one after
the other (base first).

Run from the repository root, on a quiet machine (nothing else running):
    .venv/bin/python benchmarks/bench_main_job.py [--base COMMIT] [--repeats N] [--target RATIO] [--tests] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.doc_sections import write_section  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results" / "main_job.json"
README = REPO / "benchmarks" / "README.md"
# The commit the change to a job per campaign and stage started from (it had a job per table and figure),
# and the campaigns it had.
DEFAULT_BASE = "4cb14a1"
DEFAULT_CAMPAIGNS = ["kuka-compliance", "kuka-cubes", "kuka-twin", "kuka-twin-2019"]
TEST_COMMAND = [".venv/bin/python", "-m", "pytest", "-q"]  # the README's, after the install


def snakemake(checkout: Path, results: str, campaigns: list[str], *extra: str) -> subprocess.CompletedProcess:
    config = [f"results_dir={results}", f"campaigns=[{','.join(campaigns)}]"]
    env = {**os.environ, "PYTHONPATH": str(checkout / "src")}
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "-j2", "--quiet", "all", *extra, "--config", *config],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
    )


def planned_jobs(checkout: Path, campaigns: list[str]) -> int:
    """Jobs a run from empty results plans (`snakemake -n`), the `all` target aside."""
    with tempfile.TemporaryDirectory() as results:
        out = snakemake(checkout, results, campaigns, "-n", "--quiet", "rules")
    # the job-stats table (Snakemake prints it twice with --quiet rules): rows up to its "total"
    table = re.search(r"^job\s+count\n(?:-+\s+-+\n)?(.*?)^total\s+(\d+)$", out.stdout, flags=re.MULTILINE | re.DOTALL)
    if table is None:
        sys.exit(f"no job table in the dry run of {checkout}:\n{out.stdout[-2000:]}{out.stderr[-2000:]}")
    counts = re.findall(r"^(\S+)\s+(\d+)$", table.group(1), flags=re.MULTILINE)
    return sum(int(n) for rule, n in counts if rule != "all")


def timed_run(checkout: Path, campaigns: list[str], keep: Path | None = None) -> float:
    """Seconds of one run from empty results; its results are left in `keep` (emptied first) if given."""
    with tempfile.TemporaryDirectory() as scratch:
        results = Path(scratch) if keep is None else keep
        if keep is not None:
            shutil.rmtree(keep, ignore_errors=True)
            keep.mkdir(parents=True)
        started = time.perf_counter()
        out = snakemake(checkout, str(results), campaigns)
        seconds = time.perf_counter() - started
    if out.returncode != 0:
        sys.exit(f"snakemake failed in {checkout}:\n{out.stderr[-3000:]}")
    return seconds


def test_command_seconds(checkout: Path) -> tuple[float, str]:
    """The README's test command in `checkout`, with this environment's interpreter and that
    checkout's library first on the path."""
    env = {**os.environ, "PYTHONPATH": str(checkout / "src")}
    started = time.perf_counter()
    out = subprocess.run([sys.executable, *TEST_COMMAND[1:]], cwd=checkout, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if out.returncode != 0:
        sys.exit(f"the test command failed in {checkout}:\n{out.stdout[-3000:]}")
    return seconds, out.stdout.strip().splitlines()[-1]


def markdown(record: dict) -> str:
    base, this = record["base"], record["this"]
    lines = [
        f"Last measured {record['date']} by `bench_main_job.py` ({record['campaigns_note']}), "
        f"runs alternated base/this:",
        "",
        "| checkout | planned jobs | wall per run (s) | median (s) |",
        "|---|---|---|---|",
    ]
    for label, run in (("base " + base["commit"], base), ("this " + this["commit"], this)):
        walls = ", ".join(f"{s:.0f}" for s in run["wall_s"])
        lines.append(f"| {label} | {run['jobs']} | {walls} | {statistics.median(run['wall_s']):.0f} |")
    target = record.get("target", 1.0)
    lines += ["", f"Ratio this / base (medians): **{record['ratio']:.2f}** (target: at most {target:g})."]
    if "tests" in record:
        lines += ["", f"The test command (`{' '.join(TEST_COMMAND)}`), each checkout's own tests:", ""]
        lines += ["| checkout | seconds | summary |", "|---|---|---|"]
        for label in ("base", "this"):
            tests = record["tests"][label]
            lines.append(f"| {label} {record[label]['commit']} | {tests['seconds']:.0f} | {tests['summary']} |")
        lines += ["", f"Ratio this / base: **{record['tests']['ratio']:.2f}** (target: at most 1)."]
    return "\n".join(lines)


def write(record: dict) -> None:
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    write_section(README, "bench_main_job", markdown(record))


def commit_of(checkout: Path) -> str:
    return subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=checkout, capture_output=True, text=True, check=True
    ).stdout.strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default=DEFAULT_BASE, help="commit to compare with (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=2, help="runs of each checkout (default: %(default)s)")
    parser.add_argument("--campaigns", nargs="+", default=DEFAULT_CAMPAIGNS)
    parser.add_argument(
        "--target", type=float, default=1.0, help="the ratio this / base to reach (default: %(default)s)"
    )
    parser.add_argument("--tests", action="store_true", help="also time the README's test command in both")
    parser.add_argument("--keep", type=Path, help="leave each checkout's last results in KEEP/base and KEEP/this")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        base = Path(folder) / "base"
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(base), args.base], cwd=REPO, check=True, capture_output=True
        )
        try:
            checkouts = {"base": base, "this": REPO}
            record = {
                "date": date.today().isoformat(),
                "campaigns": args.campaigns,
                "campaigns_note": f"{len(args.campaigns)} campaigns: {', '.join(args.campaigns)}",
                "target": args.target,
            }
            for name, checkout in checkouts.items():
                record[name] = {
                    "commit": commit_of(checkout),
                    "jobs": planned_jobs(checkout, args.campaigns),
                    "wall_s": [],
                }
            for repeat in range(args.repeats):
                for name, checkout in checkouts.items():
                    keep = args.keep / name if args.keep and repeat == args.repeats - 1 else None
                    seconds = timed_run(checkout, args.campaigns, keep)
                    record[name]["wall_s"].append(round(seconds, 1))
                    print(f"run {repeat + 1}, {name}: {seconds:.1f} s", flush=True)
            if args.tests:
                record["tests"] = {}
                for name, checkout in checkouts.items():
                    seconds, summary = test_command_seconds(checkout)
                    record["tests"][name] = {"seconds": round(seconds, 1), "summary": summary}
                    print(f"tests, {name}: {seconds:.1f} s ({summary})", flush=True)
                record["tests"]["ratio"] = record["tests"]["this"]["seconds"] / record["tests"]["base"]["seconds"]
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(base)], cwd=REPO, capture_output=True)
    record["ratio"] = statistics.median(record["this"]["wall_s"]) / statistics.median(record["base"]["wall_s"])
    write(record)
    print(markdown(record))


if __name__ == "__main__":
    main()
