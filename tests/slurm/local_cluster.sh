#!/usr/bin/env bash
# The private cluster of tools/slurm_cluster.sh: a job array runs every one of
# its tasks, slurmctld listens inside the cluster's network namespace and no
# Slurm port is open in the machine's own, and every daemon is gone after.
# Exit 77 (skipped) where Slurm is not installed: `bash tools/setup.sh test`
# installs it.
set -euo pipefail
root=$1
command -v slurmctld >/dev/null || {
    echo "Slurm is not installed (bash tools/setup.sh test installs it)"
    exit 77
}
out=$(mktemp -d "${TMPDIR:-/tmp}/cambium-slurm-test.XXXXXX")
trap 'rm -rf "$out"' EXIT
"$root/tools/slurm_cluster.sh" with bash -c '
    set -euo pipefail
    out=$1 outside=$2
    dir=$(dirname "$SLURM_CONF")
    cat "$dir/netns.pid" "$dir/munged.pid" "$dir/slurmctld.pid" "$dir/slurmd.pid" >"$out/pids"
    sbatch --wait --array=1-3 --output=/dev/null --chdir="$out" \
        --wrap "echo \$SLURM_ARRAY_TASK_ID >task.\$SLURM_ARRAY_TASK_ID" >/dev/null
    for i in 1 2 3; do
        [ "$(cat "$out/task.$i" 2>/dev/null)" = "$i" ] || { echo "array task $i did not run"; exit 1; }
    done
    ss -ltn | grep -q ":6817 " || { echo "slurmctld does not listen in its namespace"; exit 1; }
    if nsenter --net="/proc/$outside/ns/net" -- ss -ltn | grep -E ":681[78] "; then
        echo "a Slurm port is open outside the cluster'"'"'s network namespace"
        exit 1
    fi
' bash "$out" $$
[ "$(wc -w <"$out/pids")" -eq 4 ] || { echo "expected 4 pids (namespace, munged, slurmctld, slurmd)"; exit 1; }
for pid in $(cat "$out/pids"); do
    if kill -0 "$pid" 2>/dev/null && ! grep -q '^State:.*Z' "/proc/$pid/status"; then
        echo "process $pid of the cluster is still running: $(tr '\0' ' ' <"/proc/$pid/cmdline")"
        exit 1
    fi
done
echo "a job array of 3 tasks ran on the private cluster; nothing listened outside it; all stopped"
