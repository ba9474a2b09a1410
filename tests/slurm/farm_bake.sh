#!/usr/bin/env bash
# `cambium bake … --frames --slurm` on the private cluster
# (tools/slurm_cluster.sh): the Populus sequence as a job array of several
# chunks followed with --wait writes the frames a local bake writes, byte for
# byte past the header's UUID; a second submission while the first's jobs
# are queued or running is refused with exit 2.  Exit 77 (skipped) where
# Slurm is not installed.
set -euo pipefail
root=$1 cambium=$2
command -v slurmctld >/dev/null || {
    echo "Slurm is not installed (bash tools/setup.sh test installs it)"
    exit 77
}
out=$(mktemp -d "${TMPDIR:-/tmp}/cambium-farm-test.XXXXXX")
trap '[ -n "${KEEP:-}" ] || rm -rf "$out"' EXIT
mkdir -p "$out/local" "$out/farm"
args=("$root/examples/populus/populus.json" --frames 1-12 --fps-per-year 2 --voxel-size 0.05
    --device cpu)
"$cambium" bake "${args[@]}" -o "$out/local/p.####.vdb" >/dev/null
"$root/tools/slurm_cluster.sh" with bash -c '
    set -euo pipefail
    cambium=$1 out=$2
    shift 2
    # The first submission on hold, so that the second surely meets it
    # queued; released once the second is refused.
    "$cambium" bake "$@" -o "$out/farm/p.####.vdb" --slurm --chunk 3 --slurm-arg=--hold \
        >"$out/first.txt"
    if "$cambium" bake "$@" -o "$out/farm/p.####.vdb" --slurm --chunk 3 >"$out/second.txt" 2>&1; then
        echo "a second submission while the first is queued was accepted"; exit 1
    else
        status=$?
        [ $status -eq 2 ] || { echo "the second submission exited $status, not 2"; cat "$out/second.txt"; exit 1; }
        grep -q "still queued or running" "$out/second.txt" || { cat "$out/second.txt"; exit 1; }
    fi
    job=$(sed -n "s/^submitted job array \([0-9]*\):.*/\1/p" "$out/first.txt")
    scontrol release "$job"
    for _ in $(seq 600); do
        [ -z "$(squeue -h -j "$job" -o %i)" ] && break
        sleep 0.5
    done
    [ -z "$(squeue -h -j "$job" -o %i)" ] || { echo "the first array did not end in 300 s"; exit 1; }
    # Then once more, followed with --wait: every frame is kept (--resume).
    "$cambium" bake "$@" -o "$out/farm/p.####.vdb" --slurm --chunk 3 --wait | tee "$out/wait.txt"
    grep -q "^12 of 12 frames written and of this plan; 0 chunks failed" "$out/wait.txt"
    [ "$(grep -c "^chunk .* done$" "$out/wait.txt")" -eq 3 ]
' bash "$cambium" "$out" "${args[@]}"
for f in $(seq -f %04g 1 12); do
    cmp -s -i 57 "$out/local/p.$f.vdb" "$out/farm/p.$f.vdb" || {
        echo "frame $f differs from the local bake"
        exit 1
    }
done
echo "12 frames baked as a Slurm job array equal the local bake; a second submission was refused"
