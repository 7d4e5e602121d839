#!/usr/bin/env bash
# A one-node SLURM cluster on this machine, to run the workflow through the snakemake SLURM executor
# plugin exactly as on a real cluster (docs/cluster.md). Run as root; safe to run again (it installs
# what is missing, rewrites the configuration, restarts a daemon only when its configuration changed
# or it is not running). No systemd is assumed: munged, slurmdbd, slurmctld and slurmd are started
# directly as daemons.
#
#   bash workflow/profiles/slurm/setup-local-node.sh [--accounting | --no-accounting] [--stop]
#
# The node is named after `hostname -s`, has this machine's CPUs (nproc) and its memory (free -m)
# less SLURM_LOCAL_MEMORY_MARGIN_MB (default 1024) for the system and the daemons; one partition,
# "local" (SLURM_LOCAL_PARTITION), is the default. select/cons_tres with CR_Core_Memory makes a
# job's --mem a consumable resource (jobs wait for memory as they wait for cores), and
# jobacct_gather/linux with OverMemoryKill ends a job that uses more than it asked for.
#
# Job status: the plugin asks `sacct` by default, and sacct needs slurmdbd.
#   --no-accounting (default): no database. MinJobAge=600 keeps finished jobs in the controller for
#     10 minutes, so `--slurm-status-command squeue` sees every job's end; a line per finished job
#     (id, state, start, end, node) goes to /var/log/slurm/jobcomp.log (jobcomp/filetxt).
#   --accounting: also installs MariaDB and slurmdbd, so that `sacct` works and keeps each job's
#     elapsed time and peak memory (MaxRSS): what run-local.sh measures with.
#   --stop: stops the daemons this script started (by their pid files) and exits.
set -euo pipefail

ACCOUNTING=0
STOP=0
for argument in "$@"; do
    case "$argument" in
        --accounting) ACCOUNTING=1 ;;
        --no-accounting) ACCOUNTING=0 ;;
        --stop) STOP=1 ;;
        -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
        *) echo "setup-local-node.sh: unknown argument $argument (see --help)" >&2; exit 2 ;;
    esac
done
if [[ $EUID -ne 0 ]]; then
    echo "setup-local-node.sh: run as root (it installs packages and starts the SLURM daemons)" >&2
    exit 1
fi

NODE=$(hostname -s)
PARTITION=${SLURM_LOCAL_PARTITION:-local}
CLUSTER=${SLURM_LOCAL_CLUSTER:-remaster-local}
MARGIN_MB=${SLURM_LOCAL_MEMORY_MARGIN_MB:-1024}
CONF_DIR=/etc/slurm
RUN_DIR=/run/slurm
LOG_DIR=/var/log/slurm
STATE_DIR=/var/lib/slurm
DB_NAME=slurm_acct_db

say() { echo "setup-local-node: $*"; }

pid_alive() {  # pid_alive PIDFILE: the daemon of that pid file is running
    [[ -s "$1" ]] && kill -0 "$(cat "$1")" 2>/dev/null
}

stop_daemon() {  # stop_daemon NAME PIDFILE: SIGTERM the pid of its pid file, wait until it is gone
    local name=$1 pidfile=$2 pid
    if pid_alive "$pidfile"; then
        pid=$(cat "$pidfile")
        say "stopping $name (pid $pid)"
        kill "$pid"
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    fi
    rm -f "$pidfile"
}

if [[ $STOP -eq 1 ]]; then
    stop_daemon slurmd "$RUN_DIR/slurmd.pid"
    stop_daemon slurmctld "$RUN_DIR/slurmctld.pid"
    stop_daemon slurmdbd "$RUN_DIR/slurmdbd.pid"
    stop_daemon munged /run/munge/munged.pid
    [[ -x /etc/init.d/mariadb ]] && /etc/init.d/mariadb status >/dev/null 2>&1 && /etc/init.d/mariadb stop
    exit 0
fi

# --- packages --------------------------------------------------------------------------------
packages=(munge slurmctld slurmd slurm-client)
[[ $ACCOUNTING -eq 1 ]] && packages+=(slurmdbd mariadb-server)
missing=()
for package in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
if (( ${#missing[@]} )); then
    say "installing ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# --- munge -----------------------------------------------------------------------------------
if [[ ! -s /etc/munge/munge.key ]]; then
    say "creating the munge key"
    mungekey --create --keyfile /etc/munge/munge.key
fi
chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
install -d -o munge -g munge -m 0755 /run/munge
install -d -o munge -g munge -m 0700 /var/log/munge /var/lib/munge
if ! pid_alive /run/munge/munged.pid; then
    say "starting munged"
    runuser -u munge -- /usr/sbin/munged
fi
for _ in $(seq 50); do munge -n </dev/null 2>/dev/null | unmunge >/dev/null 2>&1 && break; sleep 0.2; done
munge -n </dev/null | unmunge >/dev/null || { echo "setup-local-node: munge does not work" >&2; exit 1; }

# --- slurm.conf ------------------------------------------------------------------------------
CPUS=$(nproc)
TOTAL_MB=$(free -m | awk '/^Mem:/ {print $2}')
REAL_MB=$(( TOTAL_MB - MARGIN_MB ))
install -d -o slurm -g slurm -m 0755 "$RUN_DIR" "$LOG_DIR" "$STATE_DIR" "$STATE_DIR/slurmctld"
install -d -m 0755 "$STATE_DIR/slurmd" "$CONF_DIR"

if [[ $ACCOUNTING -eq 1 ]]; then
    accounting="AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=$NODE
JobAcctGatherFrequency=task=1"
else
    accounting="AccountingStorageType=accounting_storage/none
JobAcctGatherFrequency=task=1"
fi

new_conf=$(cat <<EOF
# Written by workflow/profiles/slurm/setup-local-node.sh: one node, this machine.
ClusterName=$CLUSTER
SlurmctldHost=$NODE
SlurmUser=slurm
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$STATE_DIR/slurmctld
SlurmdSpoolDir=$STATE_DIR/slurmd
SlurmctldPidFile=$RUN_DIR/slurmctld.pid
SlurmdPidFile=$RUN_DIR/slurmd.pid
SlurmctldLogFile=$LOG_DIR/slurmctld.log
SlurmdLogFile=$LOG_DIR/slurmd.log
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/affinity
ReturnToService=2
SchedulerType=sched/backfill
# Cores and memory are both consumable: a job's --mem is reserved on the node.
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
# Every job's memory is sampled each second; a job above its --mem is ended.
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherParams=OverMemoryKill
$accounting
# A finished job stays visible to squeue for 10 min (the plugin's squeue status needs >= 120 s).
MinJobAge=600
JobCompType=jobcomp/filetxt
JobCompLoc=$LOG_DIR/jobcomp.log
SlurmctldTimeout=120
SlurmdTimeout=300
InactiveLimit=0
KillWait=30
Waittime=0
NodeName=$NODE CPUs=$CPUS RealMemory=$REAL_MB State=UNKNOWN
PartitionName=$PARTITION Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
)

conf_changed=0
if [[ ! -f $CONF_DIR/slurm.conf ]] || [[ "$(cat $CONF_DIR/slurm.conf)" != "$new_conf" ]]; then
    printf '%s\n' "$new_conf" > $CONF_DIR/slurm.conf
    chmod 644 $CONF_DIR/slurm.conf
    conf_changed=1
    say "wrote $CONF_DIR/slurm.conf ($NODE: $CPUS CPUs, RealMemory=$REAL_MB MB, partition $PARTITION)"
fi

# --- accounting: MariaDB + slurmdbd ----------------------------------------------------------
if [[ $ACCOUNTING -eq 1 ]]; then
    if ! /etc/init.d/mariadb status >/dev/null 2>&1; then
        say "starting MariaDB"
        /etc/init.d/mariadb start >/dev/null
    fi
    DBD_CONF=$CONF_DIR/slurmdbd.conf
    password=$(sed -n 's/^StoragePass=//p' "$DBD_CONF" 2>/dev/null || true)
    [[ -n $password ]] || password=$(head -c 18 /dev/urandom | base64 | tr -dc 'A-Za-z0-9')
    mysql -u root <<EOF
CREATE DATABASE IF NOT EXISTS $DB_NAME;
CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY '$password';
ALTER USER 'slurm'@'localhost' IDENTIFIED BY '$password';
GRANT ALL ON $DB_NAME.* TO 'slurm'@'localhost';
FLUSH PRIVILEGES;
EOF
    new_dbd=$(cat <<EOF
# Written by workflow/profiles/slurm/setup-local-node.sh
AuthType=auth/munge
DbdHost=$NODE
SlurmUser=slurm
PidFile=$RUN_DIR/slurmdbd.pid
LogFile=$LOG_DIR/slurmdbd.log
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=slurm
StoragePass=$password
StorageLoc=$DB_NAME
EOF
)
    if [[ ! -f $DBD_CONF ]] || [[ "$(cat $DBD_CONF)" != "$new_dbd" ]]; then
        printf '%s\n' "$new_dbd" > $DBD_CONF
        chown slurm:slurm $DBD_CONF && chmod 600 $DBD_CONF
        stop_daemon slurmdbd "$RUN_DIR/slurmdbd.pid"
    fi
    chown slurm:slurm $DBD_CONF && chmod 600 $DBD_CONF
    if ! pid_alive "$RUN_DIR/slurmdbd.pid"; then
        say "starting slurmdbd"
        /usr/sbin/slurmdbd
    fi
    for _ in $(seq 100); do sacctmgr -n list cluster >/dev/null 2>&1 && break; sleep 0.2; done
    if ! sacctmgr -n -P list cluster format=cluster | grep -qx "$CLUSTER"; then
        sacctmgr -i add cluster "$CLUSTER" >/dev/null
    fi
else
    stop_daemon slurmdbd "$RUN_DIR/slurmdbd.pid"
fi

# --- slurmctld, slurmd -----------------------------------------------------------------------
if [[ $conf_changed -eq 1 ]]; then
    stop_daemon slurmd "$RUN_DIR/slurmd.pid"
    stop_daemon slurmctld "$RUN_DIR/slurmctld.pid"
fi
if ! pid_alive "$RUN_DIR/slurmctld.pid"; then
    say "starting slurmctld"
    /usr/sbin/slurmctld
fi
if ! pid_alive "$RUN_DIR/slurmd.pid"; then
    say "starting slurmd"
    /usr/sbin/slurmd
fi

# --- wait for the node -----------------------------------------------------------------------
state=""
for i in $(seq 60); do
    state=$(sinfo -h -n "$NODE" -o %t 2>/dev/null | head -1 || true)
    case "$state" in
        idle|mix|alloc) break ;;
        down*|drain*|drng*) scontrol update NodeName="$NODE" State=RESUME 2>/dev/null || true ;;
    esac
    sleep 1
done
if [[ ! $state =~ ^(idle|mix|alloc)$ ]]; then
    echo "setup-local-node: node $NODE is '$state' after 60 s; see $LOG_DIR/slurmctld.log and slurmd.log" >&2
    sinfo -N -l >&2 || true
    exit 1
fi
sinfo -N -o "%N %P %t %c %m"
