"""Will a campaign's jobs fit in memory? Estimated from its rows before any fit, so that a campaign
too large for the memory a job may use is refused by its first job with a message that says what
to do, not ended half-way by the kernel's out-of-memory killer.

Two jobs grow with the rows; the estimate is the larger. The accuracy's (`fit_summary`): its
theoretical accuracy holds every posterior draw's error at every optimization configuration and the
interval summary a copy of them, 16 bytes a pair, up to THEORETICAL_PAIRS pairs (beyond, a systematic
sample of them: `remaster.inference.metrics.theoretical_errors`). The loop closure's: it fits at most
`loop_closure/fit_rows` rows whatever the campaign's size, its MCMC refit evaluating every walker at
every fitted row at once. Besides, every job holds a few kB a row (the readings, predictions and
residuals of every row). Measured by `benchmarks/bench_scale_workflow.py` (its table in
benchmarks/README.md): the accuracy job 2.8 GB at 100,000 rows and 3.5 GB at 1,000,000; the loop
closure 1.2 GB fitting 7,000 rows, 2.7 GB fitting 17,500 (of 70,000), 3.4 GB fitting 20,000 (of
700,000), and in-process 3.2 GB fitting 21,000 (of a 30,000-row campaign's 21,000), its peak in
the MCMC refit.
"""

from __future__ import annotations

from ..errors import InputError

BASE_BYTES = 0.5e9  # a job's resident size with a small campaign: Python, NumPy, pandas, Numba, Pinocchio
PAIR_BYTES = 16  # a draw x configuration pair of the theoretical accuracy: its error and the summary's copy
# draw x configuration pairs the theoretical accuracy evaluates at most (2.2 GB at PAIR_BYTES):
# 2000 draws at 70,000 configurations; a million-row campaign's 700,000 would be 22 GB
THEORETICAL_PAIRS = 140_000_000
BYTES_PER_ROW = 1.5e3  # the rest of a job's per-row cost: (3.5 - 0.5 - 2.2) GB over 1,000,000 rows, rounded up
# the loop closure's cost per row it fits: (3.24 - 0.5) GB over 21,000 fitted rows, rounded up
BYTES_PER_FITTED_ROW = 1.3e5
GB = 1e9


def peak_estimate(rows: int, draws: int = 2000, fit_rows: int = 0) -> float:
    """Bytes the largest job of a campaign of `rows` rows (its largest sensor) is expected to
    need at its peak, for `draws` posterior draws in the theoretical accuracy and a loop closure
    fitting at most `fit_rows` rows (`loop_closure/fit_rows`; 0: its job not counted)."""
    rows = max(int(rows), 0)
    every_row = BASE_BYTES + BYTES_PER_ROW * rows
    accuracy = PAIR_BYTES * min(draws * rows, THEORETICAL_PAIRS)
    loop = BYTES_PER_FITTED_ROW * min(rows, max(int(fit_rows), 0))
    return every_row + max(accuracy, loop)


def check(campaign: str, rows: int, limit: float | None, draws: int = 2000, fit_rows: int = 0) -> dict:
    """The estimate for a campaign whose largest sensor has `rows` rows against `limit` bytes per
    job (None: no limit): {'largest_sensor_rows', 'estimated_peak_gb'} (not the limit, which depends
    on the machine: the summary stays the same bytes everywhere), or InputError naming the campaign,
    its rows, the estimate and the limit when it does not fit."""
    need = peak_estimate(rows, draws, fit_rows)
    if limit is not None and need > limit:
        raise InputError(
            f"{rows} rows in its largest sensor: its largest job (the accuracy, {draws} posterior draws "
            f"at up to {THEORETICAL_PAIRS:,} draw x configuration pairs"
            + (f", or the loop closure fitting up to {min(rows, fit_rows):,} rows" if fit_rows > 0 else "")
            + f") would need about {need / GB:.1f} GB, more than the "
            f"{limit / GB:.1f} GB a job may use (max_job_memory_gb in config.yaml; by default half "
            f"this machine's memory): raise max_job_memory_gb where the machine allows it, or split "
            f"the campaign into smaller ones (by date or by pose)",
            file=campaign,
        )
    return {"largest_sensor_rows": int(rows), "estimated_peak_gb": need / GB}


# What a workflow job's own Snakemake (the script's parent in the job) adds to the script's peak:
# measured on a one-node SLURM (docs/cluster.md) at 515-525 MB beside the script; with a margin for
# clusters that limit the whole job.
SNAKEMAKE_IN_JOB = 768e6


def job_request_mb(rows: int, draws: int = 2000, attempt: int = 1, fit_rows: int = 0) -> int:
    """Memory (MB) a workflow job of a campaign of `rows` rows (its largest sensor) asks for: the
    peak estimate and the job's own Snakemake, half as much again on each retry (`attempt` 1, 2, ...)."""
    need = peak_estimate(rows, draws, fit_rows) + SNAKEMAKE_IN_JOB
    return int(need * (1 + 0.5 * (attempt - 1)) / 1e6) + 1
