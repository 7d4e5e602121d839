#!/usr/bin/env bash
# Runs the workflow on the bundled campaigns through the snakemake SLURM executor plugin with the
# project's profile (this folder: workflow/profiles/slurm) on a one-node SLURM cluster set up on this machine by
# setup-local-node.sh, from a fresh results folder, and records what was measured (docs/cluster.md).
# Run as root (the set-up starts the SLURM daemons).
#
#   bash workflow/profiles/slurm/run-local.sh [options] [-- extra snakemake arguments]
#     --checkout DIR     the repository to run (default: the one this script sits in)
#     --campaigns A,B    only these campaigns (default: every bundled one)
#     --jobs N           SLURM jobs snakemake keeps queued at once (default 2: this machine's cores)
#     --results DIR      results folder, new or an earlier run's (emptied first); default: a new
#                        folder under /tmp, removed after a successful run unless --keep
#     --out FILE         the measured result, JSON (default: <checkout>/benchmarks/results/slurm_local.json)
#     --no-accounting    no slurmdbd: job status by squeue, no peak memory per job (default: with
#                        slurmdbd + MariaDB, so that sacct gives each job's elapsed time and MaxRSS)
#     --keep             keep the results folder
# Environment: PYTHON (default <checkout>/.venv/bin/python, else python3) with snakemake and
# snakemake-executor-plugin-slurm (pip install -e '.[cluster]'); the checkout's src/ is put first
# on PYTHONPATH, so the jobs import that checkout's library.
# Exit status: snakemake's.
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
CHECKOUT=$(git -C "$HERE" rev-parse --show-toplevel)
CAMPAIGNS=""
JOBS=2
RESULTS=""
OUT=""
ACCOUNTING=1
KEEP=0
while (( $# )); do
    case "$1" in
        --checkout) CHECKOUT=$(cd "$2" && pwd); shift 2 ;;
        --campaigns) CAMPAIGNS=$2; shift 2 ;;
        --jobs) JOBS=$2; shift 2 ;;
        --results) RESULTS=$2; shift 2 ;;
        --out) OUT=$2; shift 2 ;;
        --no-accounting) ACCOUNTING=0; shift ;;
        --keep) KEEP=1; shift ;;
        -h|--help) sed -n '2,21p' "$0"; exit 0 ;;
        --) shift; break ;;
        *) echo "run-local.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done
OUT=${OUT:-$CHECKOUT/benchmarks/results/slurm_local.json}
if [[ -z ${PYTHON:-} ]]; then
    if [[ -x $CHECKOUT/.venv/bin/python ]]; then PYTHON=$CHECKOUT/.venv/bin/python; else PYTHON=$(command -v python3); fi
fi
"$PYTHON" -c "import snakemake_executor_plugin_slurm" 2>/dev/null || {
    echo "run-local.sh: $PYTHON has no snakemake-executor-plugin-slurm: pip install -e '$CHECKOUT[cluster]'" >&2
    exit 1
}

if (( ACCOUNTING )); then bash "$HERE/setup-local-node.sh" --accounting; else bash "$HERE/setup-local-node.sh" --no-accounting; fi

if [[ -z $RESULTS ]]; then
    RESULTS=$(mktemp -d /tmp/remaster-slurm-XXXXXX)
else
    if [[ -d $RESULTS && -n $(ls -A "$RESULTS") && ! -f $RESULTS/snakemake.log ]]; then
        echo "run-local.sh: $RESULTS is not empty and not an earlier run's results folder: give a new folder" >&2
        exit 2
    fi
    rm -rf "$RESULTS"
    mkdir -p "$RESULTS"
fi
RESULTS=$(cd "$RESULTS" && pwd)

config=("results_dir=$RESULTS")
[[ -n $CAMPAIGNS ]] && config+=("campaigns=[$CAMPAIGNS]")
slurm_args=(--slurm-logdir "$RESULTS/slurm_logs" --slurm-keep-successful-logs
            --slurm-init-seconds-before-status-checks 5)
# Without slurmdbd, sacct answers "accounting storage is disabled": the plugin is told to use squeue.
(( ACCOUNTING )) || slurm_args+=(--slurm-status-command squeue)

cd "$CHECKOUT"
export PYTHONPATH="$CHECKOUT/src${PYTHONPATH:+:$PYTHONPATH}"
export REMASTER_SLURM_PARTITION=${REMASTER_SLURM_PARTITION:-local}
unset REMASTER_SLURM_ACCOUNT
command=("$PYTHON" -m snakemake --workflow-profile "$HERE" --jobs "$JOBS"
         --config "${config[@]}" "${slurm_args[@]}" "$@")
echo "run-local.sh: ${command[*]}"
started=$(date +%s.%N)
status=0
"${command[@]}" > "$RESULTS/snakemake.log" 2>&1 || status=$?
ended=$(date +%s.%N)
tail -n 5 "$RESULTS/snakemake.log"

mkdir -p "$(dirname "$OUT")"
"$PYTHON" "$HERE/summarize-run.py" --results "$RESULTS" --checkout "$CHECKOUT" --started "$started" \
    --ended "$ended" --status "$status" --jobs "$JOBS" --campaigns "$CAMPAIGNS" --accounting "$ACCOUNTING" \
    --command "${command[*]}" --out "$OUT"
echo "run-local.sh: snakemake exited $status; measured result in $OUT"
if (( ! KEEP && status == 0 )) && [[ $RESULTS == /tmp/remaster-slurm-* ]]; then
    rm -rf "$RESULTS"
else
    echo "run-local.sh: results kept in $RESULTS"
fi
exit "$status"
