#!/usr/bin/env bash
# Failure on the private cluster (tools/slurm_cluster.sh): 27 Populus frames
# as a job array of 3 chunks followed with --wait; one task's bake is killed
# (kill -9) and another task cancelled (scancel) after each wrote a frame.
# The final job submits both chunks again, the sequence completes, the frames
# finished before the failures are kept (not written again), and every frame
# equals the local bake byte for byte past the header's UUID.  Exit 77
# (skipped) where Slurm is not installed.
set -euo pipefail
source "$(dirname "$0")/common.sh"
# (--min-radius 0: the twigs as they are; thickened, the frames bake 1.8
# times as long, and the test is about the farm, not the bake)
args=("$root/examples/populus/populus.json" --frames 1-27 --fps-per-year 1 --voxel-size 0.08
    --device cpu --min-radius 0)
farm_test '
    farm=$out/farm/p.frames.vdb.farm
    "$cambium" bake "$@" -o "$out/farm/p.####.vdb" --slurm --chunk 9 --wait >"$out/wait.txt" 2>&1 &
    waiter=$!
    # Each as soon as it has written a frame (9 frames a chunk: 1-9, 10-18,
    # 19-27): task 1 (frames 10-18) cancelled, chunk 3'"'"'s bake killed.
    written() { ls "$out"/farm/p.00"$1"*.vdb 2>/dev/null | head -1; }
    for _ in $(seq 3000); do [ -n "$(written 1)" ] && break; sleep 0.1; done
    job=$(head -1 "$farm/jobs")
    scancel "${job}_1"
    sleep 0.5
    stat -c "%n %i" "$out"/farm/p.001*.vdb >"$out/kept.txt"
    for _ in $(seq 3000); do [ -n "$(written 2)" ] && break; sleep 0.1; done
    # (The bake itself: "[-]" keeps the pattern from matching this script.)
    pid=$(pgrep -f -- "^[^ ]*cambium bake .*[-]-frames 19-27 " | head -1)
    [ -n "$pid" ] || { echo "chunk 3 is not running"; cat "$out/wait.txt"; exit 1; }
    kill -9 "$pid"
    sleep 0.5
    stat -c "%n %i" "$out"/farm/p.002*.vdb >>"$out/kept.txt"
    # Both before their chunks were done (else this machine was too slow to
    # catch them: a failure of the test, not of the farm).
    [ "$(grep -c "p.001" "$out/kept.txt")" -lt 9 ] && [ "$(grep -c "p.002" "$out/kept.txt")" -lt 9 ] || {
        echo "a chunk finished before it was cancelled or killed"; cat "$out/kept.txt"; exit 1; }
    status=0
    wait "$waiter" || status=$?
    cat "$out/wait.txt"
    [ $status -eq 0 ] || { echo "--wait exited $status"; cat "$farm"/final-*.log; exit 1; }
    grep -q "^27 of 27 frames written and of this plan; 0 chunks failed" "$out/wait.txt"
    # Every attempt followed, in order: chunk 2 cancelled and chunk 3
    # killed, both submitted again, then done.
    history() { grep "^chunk $1 " "$out/wait.txt" | sed "s|^chunk $1 frames [0-9-]* ||" | paste -sd"|"; }
    # (Slurm signals the script and the bake at once: the script rarely
    # lives to write the status of the bake, 143.)
    [[ "$(history 2/3)" =~ ^(ended\ without\ a\ status\ \(cancelled\ or\ killed\)|failed\ \(exit\ 143\))\|submitted\ again\|done$ ]] &&
        [ "$(history 3/3)" = "failed (exit 137)|submitted again|done" ] || {
        echo "--wait did not follow chunks 2 and 3 through their attempts"; exit 1; }
    grep -q "^submitted chunks 2, 3 again" "$farm"/final-*.log || {
        echo "the final job did not submit chunks 2 and 3 again"; cat "$farm"/final-*.log; exit 1; }
    grep -q "\"attempts\": 2" "$farm/manifest.json"
    # The frames finished before the failures were kept: the same files.
    while read -r name inode; do
        [ "$(stat -c %i "$name")" = "$inode" ] || { echo "$name was written again"; exit 1; }
    done <"$out/kept.txt"
'
same_as_local 1 27
echo "27 frames: a killed and a cancelled task were submitted again by the final job; the frames they had written were kept and every frame equals the local bake"
