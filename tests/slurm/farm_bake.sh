#!/usr/bin/env bash
# `cambium bake … --frames --slurm` on the private cluster
# (tools/slurm_cluster.sh): the Populus sequence as a job array of several
# chunks followed with --wait writes the frames a local bake writes, byte for
# byte past the header's UUID; a second submission while the first's jobs
# are queued or running is refused with exit 2, and `cambium farm` says its
# chunks are queued.  Exit 77 (skipped) where
# Slurm is not installed.
set -euo pipefail
source "$(dirname "$0")/common.sh"
args=("$root/examples/populus/populus.json" --frames 1-12 --fps-per-year 2 --voxel-size 0.05
    --device cpu)
farm_test '
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
    # While it is held, `cambium farm DIR` says so of every chunk, exit 1.
    status=0
    "$cambium" farm "$out/farm/p.frames.vdb.farm" >"$out/held.txt" || status=$?
    [ $status -eq 1 ] && [ "$(grep -c "queued or running, 4 of 4 frames to write (attempt 1)$" "$out/held.txt")" -eq 3 ] &&
        grep -q "^0 of 12 frames written and of this plan; 3 chunks queued or running, 0 chunks failed" "$out/held.txt" || {
        echo "cambium farm on a held farm exited $status:"; cat "$out/held.txt"; exit 1; }
    job=$(sed -n "s/^submitted job array \([0-9]*\):.*/\1/p" "$out/first.txt")
    final=$(sed -n "s/^final job \([0-9]*\):.*/\1/p" "$out/first.txt")
    scontrol release "$job"
    scontrol release "$final"
    for _ in $(seq 600); do
        [ -z "$(squeue -h -o %i)" ] && break
        sleep 0.5
    done
    [ -z "$(squeue -h -o %i)" ] || { echo "the first array and its final job did not end in 300 s"; exit 1; }
    grep -q "^12 of 12 frames written" "$out"/farm/p.frames.vdb.farm/final-"$final".log || {
        echo "the final job did not find every frame"; cat "$out"/farm/p.frames.vdb.farm/final-*.log; exit 1; }
    grep -q "\"complete\": true" "$out/farm/p.frames.vdb.farm/manifest.json"
    # Then once more, followed with --wait: every frame is kept (--resume).
    "$cambium" bake "$@" -o "$out/farm/p.####.vdb" --slurm --chunk 3 --wait | tee "$out/wait.txt"
    grep -q "^12 of 12 frames written and of this plan; 0 chunks failed" "$out/wait.txt"
    [ "$(grep -c "^chunk .* done$" "$out/wait.txt")" -eq 3 ]
'
same_as_local 1 12
echo "12 frames baked as a Slurm job array equal the local bake; a second submission was refused"
