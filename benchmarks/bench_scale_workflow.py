"""The whole workflow on one large simulated campaign: `snakemake -j2` end to end, its wall time,
the seconds of each rule's jobs and the peak resident memory of each job.

Run from the repository root: python benchmarks/bench_scale_workflow.py [rows] [folder]
(default 100000 rows, folder a temporary one). The campaign is `bench_scale`'s (iiwa, laser
tracker, random configurations four to a pose, 70 % optimization), the settings config.yaml's.
Memory is sampled every 0.5 s from /proc (resident set of each job's process tree), so a peak
shorter than that can be missed.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scale import write_campaign  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
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


def run(rows: int, root: Path) -> int:
    """Snakemake's exit status; the report is printed either way (a job killed for memory shows
    where the memory went)."""
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
    return snakemake.returncode


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
    rows = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    if len(sys.argv) > 2:
        sys.exit(run(rows, Path(sys.argv[2])))
    with tempfile.TemporaryDirectory() as root:
        sys.exit(run(rows, Path(root)))


if __name__ == "__main__":
    main()
