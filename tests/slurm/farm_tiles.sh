#!/usr/bin/env bash
# One Populus frame as 4 tiles on the private cluster
# (tools/slurm_cluster.sh): `cambium bake --tiles 4 --slurm --wait` runs a
# task a tile and a final job that merges them; the merged file equals the
# single bake byte for byte past the header's UUID (--half: the merge packs
# halves), the tiles are removed, and `cambium farm` says the farm is
# complete.  Exit 77 (skipped) where Slurm is not installed.
set -euo pipefail
source "$(dirname "$0")/common.sh"
args=("$root/examples/populus/populus.json" --time 10 --voxel-size 0.02 --half --device cpu)
"$cambium" bake "${args[@]}" -o "$out/local/hero.vdb" >/dev/null
export cambium out
"$root/tools/slurm_cluster.sh" with bash -c '
    set -euo pipefail
    farm=$out/farm/hero.vdb.tiles.farm
    "$cambium" bake "$@" -o "$out/farm/hero.vdb" --tiles 4 --slurm --wait >"$out/wait.txt" 2>&1 || {
        echo "--wait exited $?"; cat "$out/wait.txt" "$farm"/final-*.log; exit 1; }
    cat "$out/wait.txt"
    [ "$(grep -c "^tile [1-4]/4 done$" "$out/wait.txt")" -eq 4 ] || { echo "not every tile done"; exit 1; }
    grep -q "^merged 4 tiles into $out/farm/hero.vdb" "$farm"/final-*.log || {
        echo "the final job did not merge the tiles"; cat "$farm"/final-*.log; exit 1; }
    grep -q "^4 of 4 tiles written and of this plan, merged into $out/farm/hero.vdb; 0 tiles failed" \
        "$out/wait.txt"
    [ -z "$(ls "$farm"/tile-*.vdb 2>/dev/null)" ] || { echo "the tiles were not removed"; exit 1; }
    grep -q "\"complete\": true" "$farm/manifest.json"
    "$cambium" farm "$farm" | grep -q "^4 of 4 tiles written and of this plan, merged"
' bash "${args[@]}"
cmp -s -i 57 "$out/local/hero.vdb" "$out/farm/hero.vdb" || {
    echo "the merged tiles differ from the single bake"
    exit 1
}
echo "one frame baked as 4 tiles by a Slurm job array and merged by its final job equals the single bake"
