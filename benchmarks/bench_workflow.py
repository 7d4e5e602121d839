"""Wall time of the main job, `snakemake -j2` on the bundled campaigns, from an empty results folder.

Run from the repository root: python benchmarks/bench_workflow.py [extra snakemake arguments]
The results go to a temporary folder, so results/ is left alone.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time


def main() -> None:
    with tempfile.TemporaryDirectory() as results:
        command = [
            sys.executable,
            "-m",
            "snakemake",
            "-j2",
            "--quiet",
            "all",
            "--config",
            f"results_dir={results}",
            *sys.argv[1:],
        ]
        started = time.perf_counter()
        subprocess.run(command, check=True)
        print(f"snakemake -j2 from empty results: {time.perf_counter() - started:.1f} s")


if __name__ == "__main__":
    main()
