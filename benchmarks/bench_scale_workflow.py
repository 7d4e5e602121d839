"""The whole workflow on one large simulated campaign: `snakemake -j2` end to end, its wall time,
the seconds of each rule's jobs and the peak resident memory of each job.

Run from the repository root: python benchmarks/bench_scale_workflow.py [rows ...] [--folder F]
(default 100000 rows, folder a temporary one). The campaign is `bench_scale`'s (iiwa, laser
tracker, random configurations four to a pose, 70 % optimization), the settings config.yaml's.
Memory is sampled every 0.5 s from /proc (resident set of each job's process tree), so a peak
shorter than that can be missed.

Several sizes may be given (python benchmarks/bench_scale_workflow.py 10000 30000): each is run and
recorded in benchmarks/results/scale_workflow.json (kept with its date and commit, so that sizes
measured another day stay beside it), and the table, with how each rule's job-seconds grow between
sizes measured at the same commit (the exponent b of seconds ~ rows^b), is written into
benchmarks/README.md between its bench_scale_workflow markers. A size the workflow refuses (its
first job's memory estimate) is recorded with Snakemake's exit status and the refusal.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_scale import write_campaign  # noqa: E402

from benchmarks.doc_sections import publish  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"
PAGE = 4096


def _processes() -> dict[int, tuple[int, str, int]]:
    """{pid: (parent pid, command line, resident bytes)} of every process we can read."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            resident = int((entry / "statm").read_text().split()[1]) * PAGE
        except (OSError, IndexError, ValueError):
            continue
        out[int(entry.name)] = (parent, command, resident)
    return out


def _job_of(command: str) -> str | None:
    """The workflow script a job runs (Snakemake's copy: .snakemake/scripts/tmpXXXX.<script>.py)."""
    found = re.search(r"\.snakemake/scripts/tmp[^.]+\.(\w+)\.py", command)
    return found.group(1) if found else None


def run(rows: int, root: Path) -> dict:
    """The record of one size: Snakemake's exit status, wall seconds, and per rule its jobs'
    seconds and peak resident memory; printed either way (a job killed for memory shows where the
    memory went)."""
    raw, results = root / "raw", root / "results"
    name = f"scale-{rows}"
    if not (raw / name / "campaign.yaml").exists():
        started = time.perf_counter()
        write_campaign(raw / name, rows, np.random.default_rng(rows))
        print(f"campaign of {rows} rows written in {time.perf_counter() - started:.0f} s", flush=True)
    command = [
        sys.executable,
        "-m",
        "snakemake",
        "-j2",
        "--config",
        f"raw_dir={raw}",
        f"results_dir={results}",
        f"campaigns=[{name}]",
        "paper_twins=[]",
    ]
    peaks: dict[str, int] = defaultdict(int)
    started = time.perf_counter()
    with open(root / "snakemake.log", "w") as log:
        snakemake = subprocess.Popen(command, cwd=REPO, stdout=log, stderr=subprocess.STDOUT)
        while snakemake.poll() is None:
            table = _processes()
            for pid, (_, command_line, _) in table.items():
                job = _job_of(command_line)
                if job is None:
                    continue
                tree, resident = [pid], 0
                while tree:  # the job's process and its children
                    current = tree.pop()
                    resident += table.get(current, (0, "", 0))[2]
                    tree += [p for p, (parent, _, _) in table.items() if parent == current]
                peaks[job] = max(peaks[job], resident)
            time.sleep(0.5)
    wall = time.perf_counter() - started
    print(f"snakemake -j2 on {rows} rows: exit {snakemake.returncode}, {wall:.0f} s wall")
    seconds = job_seconds((root / "snakemake.log").read_text())
    print(f"{'rule':<40} {'job-seconds':>11} {'jobs':>5} {'peak MB':>8}")
    for rule, spent in sorted(seconds.items(), key=lambda kv: -sum(kv[1])):
        print(f"{rule:<40} {sum(spent):11.0f} {len(spent):5d} {peaks.get(rule, 0) / 1e6:8.0f}")
    others = {job: peak for job, peak in peaks.items() if job not in seconds}
    for job, peak in sorted(others.items()):
        print(f"{job + ' (script)':<40} {'':>11} {'':>5} {peak / 1e6:8.0f}")
    refused = re.search(r"(?m)^.*(?:too large|refus).*$", (root / "snakemake.log").read_text())
    return {
        "rows": rows,
        "effects": loop_effects(results / name),
        "date": date.today().isoformat(),
        "commit": _commit(),
        "exit": snakemake.returncode,
        "wall_s": wall,
        "refused": refused.group(0).strip() if refused and snakemake.returncode else None,
        # the script's peak stands for its rule's (a rule's jobs run workflow/scripts/<rule>.py)
        "rules": {
            rule: {"seconds": sum(spent), "jobs": len(spent), "peak_mb": peaks.get(rule, 0) / 1e6}
            for rule, spent in seconds.items()
        },
    }


def loop_effects(campaign_results: Path) -> list[str] | None:
    """What the loop closure added on the campaign (its sensor's loop_closure.json), None without one:
    what the stages after it cost depends on it (a residual GP is drawn jointly over configurations)."""
    found = sorted(campaign_results.glob("*/loop_closure.json"))
    return json.loads(found[0].read_text()).get("effects_added") if found else None


def _commit() -> str:
    found = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True)
    return found.stdout.strip() or "unknown"


def growth(small: dict, large: dict) -> dict[str, float]:
    """{rule: b} with seconds ~ rows^b between two sizes' records (rules of at least 2 s in both)."""
    scale = math.log(large["rows"] / small["rows"])
    out = {}
    for rule, part in large["rules"].items():
        before = small["rules"].get(rule)
        if before and before["seconds"] >= 2 and part["seconds"] >= 2:
            out[rule] = math.log(part["seconds"] / before["seconds"]) / scale
    return out


def markdown(records: list[dict]) -> str:
    records = sorted(records, key=lambda r: r["rows"])
    head = " | ".join(f"{r['rows']:,} rows ({r['date']}, {r['commit']})" for r in records)
    lines = [
        "Measured by `bench_scale_workflow.py`: `snakemake -j2` from empty results on one campaign of each size; "
        "per rule the seconds of its jobs summed (job-seconds; 1 s stamps) and the peak resident memory of "
        "its jobs, then how the seconds grow between sizes measured at the same commit (b in seconds ~ rows^b).",
        "",
        f"| | {head} |",
        "|---|" + "---|" * len(records),
        "| the loop added | " + " | ".join(", ".join(r.get("effects") or ["?"]) for r in records) + " |",
        "| wall, exit | "
        + " | ".join(
            f"{r['wall_s'] / 60:.1f} min, exit {r['exit']}" + (f": {r['refused']}" if r.get("refused") else "")
            for r in records
        )
        + " |",
    ]
    rules = sorted(  # by the largest size's seconds, ties by name: the same table from the same record
        {rule for r in records for rule in r["rules"]},
        key=lambda x: (-records[-1]["rules"].get(x, {}).get("seconds", 0), x),
    )
    for rule in rules:
        cells = []
        for r in records:
            part = r["rules"].get(rule)
            cells.append(
                "-"
                if part is None
                else f"{part['seconds']:.0f} s" + (f", {part['peak_mb']:.0f} MB" if part["peak_mb"] else "")
            )
        lines.append(f"| {rule} | " + " | ".join(cells) + " |")
    pairs = [(a, b) for a, b in zip(records, records[1:]) if a["commit"] == b["commit"] and a["exit"] == b["exit"] == 0]
    for small, large in pairs:
        grown = growth(small, large)
        if grown:
            shown = ", ".join(f"{rule} {b:.2f}" for rule, b in sorted(grown.items(), key=lambda kv: -kv[1]))
            lines += ["", f"Growth {small['rows']:,} to {large['rows']:,} rows: {shown}."]
    return "\n".join(lines)


def job_seconds(log: str) -> dict[str, list[float]]:
    """{rule: [seconds of each job]} from Snakemake's log (its time stamps have 1 s resolution)."""
    stamp, rule, started, rule_of, out = None, None, {}, {}, defaultdict(list)
    for line in log.splitlines():
        if found := re.match(r"\[(\w+ \w+ +\d+ [\d:]+ \d+)\]", line):
            stamp = time.mktime(time.strptime(found.group(1), "%a %b %d %H:%M:%S %Y"))
        elif found := re.match(r"(?:local)?rule (\w+):", line):
            rule = found.group(1)
        elif (found := re.match(r"\s+jobid: (\d+)", line)) and rule:
            started[found.group(1)], rule_of[found.group(1)], rule = stamp, rule, None
        elif (found := re.match(r"Finished jobid: (\d+)", line)) and found.group(1) in started:
            out[rule_of[found.group(1)]].append(stamp - started[found.group(1)])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", type=int, nargs="*", default=[100_000])
    parser.add_argument("--folder", type=Path, default=None, help="keep the campaigns and results here")
    parser.add_argument("--render", action="store_true", help="rewrite the table from the stored record, run nothing")
    args = parser.parse_args()
    stored = RESULTS / "scale_workflow.json"
    kept = {r["rows"]: r for r in json.loads(stored.read_text())["runs"]} if stored.exists() else {}
    for rows in [] if args.render else args.rows:
        if args.folder is not None:
            kept[rows] = run(rows, args.folder)
        else:
            with tempfile.TemporaryDirectory() as root:
                kept[rows] = run(rows, Path(root))
    records = sorted(kept.values(), key=lambda r: r["rows"])
    publish(RESULTS, "scale_workflow", {"runs": records}, markdown(records), REPO / "benchmarks" / "README.md")


if __name__ == "__main__":
    main()
