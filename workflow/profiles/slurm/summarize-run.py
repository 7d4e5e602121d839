"""The measured result of one run-local.sh run, as JSON: wall time, snakemake's exit status, the
SLURM jobs it submitted (state, elapsed time, queue wait, and with slurmdbd their peak memory), per
rule. Called by run-local.sh; reads the run's SLURM logs (one folder per rule, one file per job id:
`--slurm-logdir` with `--slurm-keep-successful-logs`), the controller's job completion log
(jobcomp/filetxt) and, with accounting, sacct."""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import re
import statistics
import subprocess
from importlib import metadata
from pathlib import Path

JOBCOMP_LOG = Path("/var/log/slurm/jobcomp.log")


def jobs_by_rule(logdir: Path) -> dict[str, str]:
    """SLURM job id -> rule, from the plugin's log files: <logdir>/rule_<rule>/<wildcards>/<id>.log."""
    found = {}
    for log in logdir.rglob("*.log"):
        top = log.relative_to(logdir).parts[0]
        if log.stem.isdigit():
            found[log.stem] = re.sub(r"^(rule|group)_", "", top)
    return found


def jobcomp_records(ids: set[str]) -> dict[str, dict[str, str]]:
    """The job completion log's line of every job in `ids` (the last one, should an id recur)."""
    records = {}
    if JOBCOMP_LOG.exists():
        for line in JOBCOMP_LOG.read_text().splitlines():
            fields = dict(token.split("=", 1) for token in line.split() if "=" in token)
            if fields.get("JobId") in ids:
                records[fields["JobId"]] = fields
    return records


def sacct_records(ids: set[str]) -> dict[str, dict[str, str]]:
    """sacct's job line of every job in `ids`, with its peak memory (MB): the sum of its steps'
    MaxRSS, since the steps run at once (the batch step holds the plugin's jobstep snakemake, step 0
    the job's own snakemake and its script), and step 0's alone."""
    if not ids:
        return {}
    query = subprocess.run(
        [
            "sacct",
            "-P",
            "-n",
            "--units=M",
            "-j",
            ",".join(sorted(ids, key=int)),
            "-o",
            "JobIDRaw,State,ElapsedRaw,MaxRSS,ReqMem,ExitCode",
        ],
        capture_output=True,
        text=True,
    )
    if query.returncode != 0:
        print(f"summarize-run: sacct failed, no peak memory recorded: {query.stderr.strip()}")
        return {}
    out = query.stdout
    records: dict[str, dict[str, str]] = {}
    for line in out.splitlines():
        job_id, state, elapsed, max_rss, req_mem, exit_code = line.split("|")
        main = job_id.split(".")[0]
        record = records.setdefault(main, {"max_rss_mb": 0.0, "step_rss_mb": 0.0})
        if "." not in job_id:
            record.update(state=state.split()[0], elapsed=elapsed, req_mem=req_mem, exit_code=exit_code)
        if max_rss:
            record["max_rss_mb"] += float(max_rss.rstrip("M"))
            if not job_id.endswith((".batch", ".extern")):
                record["step_rss_mb"] = max(record["step_rss_mb"], float(max_rss.rstrip("M")))
    return records


def seconds(start: str, end: str) -> float:
    return (dt.datetime.fromisoformat(end) - dt.datetime.fromisoformat(start)).total_seconds()


def spread(values: list[float]) -> dict[str, float]:
    return (
        {"total": round(sum(values), 1), "median": round(statistics.median(values), 1), "max": round(max(values), 1)}
        if values
        else {}
    )


def command_output(*command: str) -> str:
    try:
        return subprocess.run(command, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def markdown(summary: dict) -> str:
    """The summary as a short Markdown page: the run in a few lines, then a table of the rules."""
    lines = [
        f"# SLURM, one node: measured {summary['date'][:10]} at {summary['commit']}"
        + (
            f" with uncommitted changes ({', '.join(summary['uncommitted_changes'])})"
            if summary["uncommitted_changes"]
            else ""
        ),
        "",
        f"- {summary['what']}",
        f"- node: {summary['machine']['node']}; {summary['versions']['slurm']}, snakemake "
        f"{summary['versions']['snakemake']}, snakemake-executor-plugin-slurm "
        f"{summary['versions']['snakemake-executor-plugin-slurm']}; job status by {summary['status_query']}",
        f"- campaigns: {', '.join(summary['campaigns'])}; `--jobs {summary['jobs_option']}`",
        f"- wall time **{summary['wall_time_s']:.0f} s**, snakemake exit status {summary['exit_status']}, "
        f"steps {summary['snakemake_steps_done']}",
        f"- SLURM jobs: {summary['slurm_jobs']} ({', '.join(f'{n} {s}' for s, n in summary['slurm_states'].items())}); "
        f"job elapsed time: {summary['job_elapsed_s'].get('total')} s in all, median "
        f"{summary['job_elapsed_s'].get('median')} s, max {summary['job_elapsed_s'].get('max')} s; "
        f"the node's cores busy {100 * (summary['node_busy_fraction'] or 0):.0f} % of the wall time",
        "",
        "| rule | SLURM jobs | elapsed s (median / max) | peak MB, all steps (job's step) | asked MB (--mem) |",
        "|---|---|---|---|---|",
    ]
    for rule, entry in summary["per_rule"].items():
        elapsed = entry["elapsed_s"]
        lines.append(
            f"| {rule} | {entry['slurm_jobs']} | {elapsed.get('median', '')} / {elapsed.get('max', '')} | "
            f"{entry.get('max_rss_mb', '')} ({entry.get('max_job_step_rss_mb', '')}) | "
            f"{', '.join(map(str, entry['requested_mem_mb']))} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    for name in (
        "results",
        "checkout",
        "started",
        "ended",
        "status",
        "jobs",
        "campaigns",
        "accounting",
        "command",
        "out",
    ):
        parser.add_argument(f"--{name}", required=True)
    args = parser.parse_args()
    results, checkout = Path(args.results), Path(args.checkout)
    wall = float(args.ended) - float(args.started)

    rule_of = jobs_by_rule(results / "slurm_logs")
    ids = set(rule_of)
    completion = jobcomp_records(ids)
    accounting = sacct_records(ids) if args.accounting == "1" else {}

    per_rule: dict[str, dict[str, list]] = {}
    states: dict[str, int] = {}
    for job_id, rule in rule_of.items():
        entry = per_rule.setdefault(
            rule, {"elapsed": [], "wait": [], "rss": [], "step_rss": [], "req_mem": set(), "states": []}
        )
        record = completion.get(job_id, {})
        state = accounting.get(job_id, {}).get("state") or record.get("JobState", "UNKNOWN")
        states[state] = states.get(state, 0) + 1
        entry["states"].append(state)
        elapsed = None
        if "StartTime" in record:
            elapsed = seconds(record["StartTime"], record["EndTime"])
            entry["wait"].append(seconds(record["SubmitTime"], record["StartTime"]))
            mem = re.search(r"mem=([\d.]+)([MGT])", record.get("Tres", ""))
            if mem:
                entry["req_mem"].add(round(float(mem.group(1)) * {"M": 1, "G": 1024, "T": 1024**2}[mem.group(2)]))
        if accounting.get(job_id, {}).get("elapsed"):
            elapsed = float(accounting[job_id]["elapsed"])
            entry["rss"].append(accounting[job_id]["max_rss_mb"])
            entry["step_rss"].append(accounting[job_id]["step_rss_mb"])
        if elapsed is not None:
            entry["elapsed"].append(elapsed)

    rules = {}
    for rule, entry in sorted(per_rule.items()):
        rules[rule] = {
            "slurm_jobs": len(entry["states"]),
            "elapsed_s": spread(entry["elapsed"]),
            "queue_wait_s_median": round(statistics.median(entry["wait"]), 1) if entry["wait"] else None,
            "requested_mem_mb": sorted(entry["req_mem"]),
        }
        if entry["rss"]:
            rules[rule]["max_rss_mb"] = round(max(entry["rss"]), 1)
            rules[rule]["max_job_step_rss_mb"] = round(max(entry["step_rss"]), 1)
        failed = [s for s in entry["states"] if s != "COMPLETED"]
        if failed:
            rules[rule]["not_completed"] = failed

    log = (results / "snakemake.log").read_text(errors="replace") if (results / "snakemake.log").exists() else ""
    steps = re.findall(r"(\d+) of (\d+) steps \((\d+%)\) done", log)
    elapsed = [e for entry in per_rule.values() for e in entry["elapsed"]]
    campaigns = [c for c in args.campaigns.split(",") if c] or sorted(
        p.parent.name for p in (checkout / "data" / "raw").glob("*/campaign.yaml")
    )
    summary = {
        "what": "run-local.sh: the workflow through snakemake-executor-plugin-slurm on a one-node SLURM "
        "cluster on this machine (setup-local-node.sh), from an empty results folder",
        "date": dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        "commit": command_output("git", "-C", str(checkout), "rev-parse", "--short", "HEAD"),
        "uncommitted_changes": command_output("git", "-C", str(checkout), "status", "--porcelain", "-uno").splitlines(),
        "machine": {
            "cpus": os.cpu_count(),
            "node": command_output("sinfo", "-h", "-N", "-o", "%N %P %c CPUs %m MB"),
            "python": platform.python_version(),
        },
        "versions": {
            "slurm": command_output("sinfo", "--version"),
            "snakemake": metadata.version("snakemake"),
            "snakemake-executor-plugin-slurm": metadata.version("snakemake-executor-plugin-slurm"),
        },
        "campaigns": campaigns,
        "jobs_option": int(args.jobs),
        "status_query": "sacct (slurmdbd + MariaDB)" if args.accounting == "1" else "squeue (no slurmdbd)",
        "command": args.command,
        "exit_status": int(args.status),
        "wall_time_s": round(wall, 1),
        "snakemake_steps_done": "{} of {} ({})".format(*steps[-1]) if steps else None,
        "slurm_jobs": len(ids),
        "slurm_states": states,
        "job_elapsed_s": spread(elapsed),
        "node_busy_fraction": round(sum(elapsed) / (wall * (os.cpu_count() or 1)), 3) if wall > 0 else None,
        "per_rule": rules,
    }
    Path(args.out).write_text(json.dumps(summary, indent=2) + "\n")
    Path(args.out).with_suffix(".md").write_text(markdown(summary))
    print(
        json.dumps(
            {
                k: summary[k]
                for k in (
                    "wall_time_s",
                    "exit_status",
                    "snakemake_steps_done",
                    "slurm_jobs",
                    "slurm_states",
                    "job_elapsed_s",
                    "node_busy_fraction",
                )
            }
        )
    )


if __name__ == "__main__":
    main()
