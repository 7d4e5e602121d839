"""Cost of a fleet: `snakemake -j2` on N simulated campaigns (copies of the kuka-compliance
scenario with new seeds), for several N, to show the cost is linear in the number of campaigns.

Run from the repository root: python benchmarks/bench_fleet.py 1 5 10 25 50
Each N runs in a temporary folder; the seconds per N and per campaign are printed.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENARIO = "data/simulation/kuka-compliance.yaml"


def run(n: int) -> float:
    """Seconds of `snakemake -j2` on n fresh campaigns; the folder is kept (and named) if it fails."""
    folder = tempfile.mkdtemp(prefix=f"fleet{n}-")
    raw, results = Path(folder, "raw"), Path(folder, "results")
    subprocess.run([sys.executable, "-m", "remaster.cli", "simulate", SCENARIO, "--copies", str(n),
                    "--raw-dir", str(raw), "--truth-dir", str(Path(folder, "truth"))],
                   check=True, stdout=subprocess.DEVNULL)
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "snakemake", "-j2", "--quiet", "all", "--config",
                           f"raw_dir={raw}", f"results_dir={results}"])
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"{n} campaigns: snakemake failed (exit {done.returncode}); logs in {results}/logs")
    shutil.rmtree(folder)
    return seconds


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [1, 2, 4]
    print("campaigns  seconds  seconds per campaign")
    for n in sizes:
        seconds = run(n)
        print(f"{n:9d} {seconds:8.1f} {seconds / n:12.1f}", flush=True)


if __name__ == "__main__":
    main()
