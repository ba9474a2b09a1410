#!/usr/bin/env bash
# A private single-node Slurm cluster for tests: munge, slurmctld and slurmd
# in a network namespace of their own that has only loopback (slurmctld
# listens on every address), every file under one directory.
#
#   tools/slurm_cluster.sh start DIR     start it (DIR is created); prints nothing on success
#   tools/slurm_cluster.sh run DIR CMD…  run CMD inside the namespace, with SLURM_CONF set
#   tools/slurm_cluster.sh stop DIR      stop every daemon it started, by its pid
#   tools/slurm_cluster.sh with CMD…     start one in a temporary directory, run CMD in it,
#                                        stop it whatever CMD did; CMD's exit status
#
# Needs root (network namespaces) and Debian 12's slurmctld, slurmd,
# slurm-client and munge (tools/setup.sh installs them for the tests).
set -euo pipefail

die() {
    echo "slurm_cluster.sh: $*" >&2
    exit 1
}

# The namespace is held by a `sleep infinity` started with `unshare -n`;
# everything else enters it through nsenter (which execs its command: a
# daemon started through it in the background has $! for its pid).
in_ns() {
    local dir=$1
    shift
    nsenter --net="$(netns "$dir")" -- "$@"
}
netns() {
    echo "/proc/$(cat "$1/netns.pid")/ns/net"
}

start() {
    local dir=$1
    for tool in munged mungekey slurmctld slurmd sbatch unshare nsenter ip; do
        command -v "$tool" >/dev/null || die "$tool is missing (bash tools/setup.sh test installs it)"
    done
    [ "$(id -u)" = 0 ] || die "needs root for its network namespace"
    mkdir -p "$dir"
    dir=$(cd "$dir" && pwd)
    [ ! -e "$dir/netns.pid" ] || die "$dir already holds a cluster (stop it first)"
    mkdir -p "$dir/munge" "$dir/spool" "$dir/state" "$dir/log"
    chmod 700 "$dir/munge"
    # The namespace: loopback only, and 127.0.0.2 on it, without which Slurm
    # cannot resolve "localhost" there.
    setsid unshare -n -- sleep infinity </dev/null >/dev/null 2>&1 &
    echo $! >"$dir/netns.pid"
    for _ in $(seq 50); do
        [ "$(readlink "/proc/$(cat "$dir/netns.pid")/ns/net")" != "$(readlink /proc/self/ns/net)" ] && break
        sleep 0.02
    done
    in_ns "$dir" ip link set lo up
    in_ns "$dir" ip addr add 127.0.0.2/8 dev lo

    mungekey -c -k "$dir/munge/munge.key" >/dev/null 2>&1 ||
        die "mungekey failed"
    chmod 400 "$dir/munge/munge.key"
    nsenter --net="$(netns "$dir")" -- munged --foreground --force --key-file="$dir/munge/munge.key" \
        --socket="$dir/munge/munge.socket.2" --pid-file="$dir/munge/munged.pid" \
        --seed-file="$dir/munge/munged.seed" --log-file="$dir/log/munged.log" \
        </dev/null >/dev/null 2>&1 &
    echo $! >"$dir/munged.pid"

    local cpus mem
    cpus=$(nproc)
    # Memory for jobs: what the machine has, less a little for the daemons.
    mem=$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
    cat >"$dir/slurm.conf" <<EOF
ClusterName=cambium
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket.2
CredType=cred/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
MailProg=/bin/true
ReturnToService=2
SchedulerParameters=sched_interval=1
MinJobAge=600
SlurmctldPidFile=$dir/slurmctld.daemon.pid
SlurmdPidFile=$dir/slurmd.daemon.pid
SlurmdSpoolDir=$dir/spool
StateSaveLocation=$dir/state
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
NodeName=localhost CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
    for _ in $(seq 100); do
        [ -S "$dir/munge/munge.socket.2" ] && break
        sleep 0.05
    done
    [ -S "$dir/munge/munge.socket.2" ] || die "munged did not start ($dir/log/munged.log)"
    nsenter --net="$(netns "$dir")" -- slurmctld -D -f "$dir/slurm.conf" </dev/null >"$dir/log/slurmctld.out" 2>&1 &
    echo $! >"$dir/slurmctld.pid"
    nsenter --net="$(netns "$dir")" -- slurmd -D -f "$dir/slurm.conf" </dev/null >"$dir/log/slurmd.out" 2>&1 &
    echo $! >"$dir/slurmd.pid"
    # Ready when the node is idle (each query bounded: a client that cannot
    # reach slurmctld waits long).
    local deadline=$((SECONDS + 30))
    while ((SECONDS < deadline)); do
        if in_ns "$dir" env SLURM_CONF="$dir/slurm.conf" timeout 3 sinfo -h -o %T 2>/dev/null |
            grep -q idle; then
            return 0
        fi
        sleep 0.2
    done
    die "the cluster did not come up in 30 s (logs in $dir/log)"
}

stop() {
    local dir=$1 pid
    [ -d "$dir" ] || return 0
    # The jobs first (their slurmstepd and tasks outlive slurmd), while
    # slurmctld can still cancel them.
    if [ -f "$dir/slurmctld.pid" ] && kill -0 "$(cat "$dir/slurmctld.pid")" 2>/dev/null; then
        in_ns "$dir" env SLURM_CONF="$dir/slurm.conf" timeout 5 scancel --user="$(id -un)" \
            2>/dev/null || true
        local deadline=$((SECONDS + 15))
        while ((SECONDS < deadline)) &&
            [ -n "$(in_ns "$dir" env SLURM_CONF="$dir/slurm.conf" timeout 3 squeue -h -o %i \
                2>/dev/null)" ]; do
            sleep 0.2
        done
    fi
    for name in slurmd slurmctld munged netns; do
        [ -f "$dir/$name.pid" ] || continue
        pid=$(cat "$dir/$name.pid")
        kill "$pid" 2>/dev/null || true
        for _ in $(seq 50); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
        kill -9 "$pid" 2>/dev/null || true
        rm -f "$dir/$name.pid"
    done
}

run() {
    local dir
    dir=$(cd "$1" && pwd)
    shift
    in_ns "$dir" env SLURM_CONF="$dir/slurm.conf" "$@"
}

case "${1:-}" in
start)
    [ $# = 2 ] || die "usage: start DIR"
    start "$2"
    ;;
stop)
    [ $# = 2 ] || die "usage: stop DIR"
    stop "$2"
    ;;
run)
    [ $# -ge 3 ] || die "usage: run DIR CMD…"
    dir=$2
    shift 2
    run "$dir" "$@"
    ;;
with)
    [ $# -ge 2 ] || die "usage: with CMD…"
    shift
    dir=$(mktemp -d "${TMPDIR:-/tmp}/cambium-slurm.XXXXXX")
    trap 'stop "$dir"; rm -rf "$dir"' EXIT
    trap 'exit 130' INT TERM
    start "$dir"
    status=0
    run "$dir" "$@" || status=$?
    exit $status
    ;;
*)
    die "usage: start DIR | run DIR CMD… | stop DIR | with CMD…"
    ;;
esac
