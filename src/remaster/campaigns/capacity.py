"""Will a campaign's jobs fit in memory? Estimated from its rows before any fit, so that a campaign
too large for the memory a job may use is refused by its first job with a message that says what
to do, not ended half-way by the kernel's out-of-memory killer.

Every stage's memory grows at most linearly with the rows (`benchmarks/bench_scale.py`); the
largest per row is the accuracy job's: the theoretical accuracy holds every posterior draw's
error at every configuration (2000 draws x 8 bytes) and the interval summary one sorted copy of
them, about 32 kB a row; measured 1,023 MB traced at 30,000 rows and 3.6 GB resident at 100,000.
"""

from __future__ import annotations

from ..errors import InputError

BASE_BYTES = 0.5e9  # a job's resident size with a small campaign: Python, NumPy, pandas, Numba, Pinocchio
BYTES_PER_ROW = 36e3  # the accuracy job's per-row cost (module docstring), rounded up
GB = 1e9


def peak_estimate(rows: int, draws: int = 2000) -> float:
    """Bytes the largest job of a campaign of `rows` rows (its largest sensor) is expected to
    need at its peak, for `draws` posterior draws in the theoretical accuracy."""
    return BASE_BYTES + BYTES_PER_ROW * (draws / 2000) * max(int(rows), 0)


def check(campaign: str, rows: int, limit: float | None, draws: int = 2000) -> dict:
    """The estimate for a campaign whose largest sensor has `rows` rows against `limit` bytes per
    job (None: no limit): {'largest_sensor_rows', 'estimated_peak_gb'} (not the limit, which depends
    on the machine: the summary stays the same bytes everywhere), or InputError naming the campaign,
    its rows, the estimate and the limit when it does not fit."""
    need = peak_estimate(rows, draws)
    if limit is not None and need > limit:
        raise InputError(
            f"{rows} rows in its largest sensor: its largest job (the accuracy, {draws} posterior draws "
            f"at every configuration) would need about {need / GB:.1f} GB, more than the "
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


def job_request_mb(rows: int, draws: int = 2000, attempt: int = 1) -> int:
    """Memory (MB) a workflow job of a campaign of `rows` rows (its largest sensor) asks for: the
    peak estimate and the job's own Snakemake, half as much again on each retry (`attempt` 1, 2, ...)."""
    return int((peak_estimate(rows, draws) + SNAKEMAKE_IN_JOB) * (1 + 0.5 * (attempt - 1)) / 1e6) + 1
