"""Cost of a fleet: `snakemake -j2` on N simulated campaigns (copies of the kuka-compliance
scenario with new seeds), for several N, to show the cost is linear in the number of campaigns.

Run from the repository root: python benchmarks/bench_fleet.py 1 5 10 25 50
Each N runs in a temporary folder; the seconds per N and per campaign are printed. The copies are
one robot measured again and again on one day (same truth, new poses and noise), so the drift
between them is known to be nil: for each N > 1 the drift flags' calibration is printed too
(`comparison.drift_calibration`: z of unit spread and about the expected number of flags when
the stated uncertainties are honest), for the paper's model and for the loop closure's.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from remaster import files
from remaster.comparing import comparison

SCENARIO = "data/simulation/kuka-compliance.yaml"


def calibration(results: Path) -> str:
    """The drift calibration of both models' drift tables of a finished run, as text."""
    parts = []
    for name in ("drift_between_campaigns", "loop_parameter_drift"):
        table = comparison.drift_calibration(files.read_csv(results / "comparison" / f"{name}.csv"))
        parts.append(f"{name}:\n{table.to_string(index=False, float_format='%.2f')}")
    return "\n".join(parts)


def run(n: int) -> tuple[float, str]:
    """Seconds of `snakemake -j2` on n fresh campaigns, and the drift calibration; the folder is
    kept (and named) if it fails."""
    folder = tempfile.mkdtemp(prefix=f"fleet{n}-")
    raw, results = Path(folder, "raw"), Path(folder, "results")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "remaster.cli",
            "simulate",
            SCENARIO,
            "--copies",
            str(n),
            "--raw-dir",
            str(raw),
            "--truth-dir",
            str(Path(folder, "truth")),
        ],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    started = time.perf_counter()
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "snakemake",
            "-j2",
            "--quiet",
            "all",
            "--config",
            f"raw_dir={raw}",
            f"results_dir={results}",
        ]
    )
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"{n} campaigns: snakemake failed (exit {done.returncode}); logs in {results}/logs")
    drift = calibration(results) if n > 1 else ""
    shutil.rmtree(folder)
    return seconds, drift


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [1, 2, 4]
    print("campaigns  seconds  seconds per campaign")
    calibrations = {}
    for n in sizes:
        seconds, calibrations[n] = run(n)
        print(f"{n:9d} {seconds:8.1f} {seconds / n:12.1f}", flush=True)
    for n, text in calibrations.items():
        if text:
            print(f"\ndrift between {n} repeat campaigns of one truth\n{text}")


if __name__ == "__main__":
    main()
