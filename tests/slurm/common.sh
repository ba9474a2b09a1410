# The farm tests' start, sourced with their arguments ROOT CAMBIUM: exit 77
# (skipped) where Slurm is not installed; a temporary directory $out with
# local/ and farm/ (kept with KEEP=1); `farm_test SCRIPT` bakes the frames
# of "${args[@]}" into local/, then runs SCRIPT with bash on a private
# cluster (tools/slurm_cluster.sh) with $cambium, $out and the arguments
# "$@"; `same_as_local FIRST LAST` compares the farm's frames with local/'s,
# byte for byte past the header's UUID.
root=$1 cambium=$2
command -v slurmctld >/dev/null || {
    echo "Slurm is not installed (bash tools/setup.sh test installs it)"
    exit 77
}
out=$(mktemp -d "${TMPDIR:-/tmp}/cambium-farm-test.XXXXXX")
trap '[ -n "${KEEP:-}" ] || rm -rf "$out"' EXIT
mkdir -p "$out/local" "$out/farm"
farm_test() {
    "$cambium" bake "${args[@]}" -o "$out/local/p.####.vdb" >/dev/null
    export cambium out
    "$root/tools/slurm_cluster.sh" with bash -c "set -euo pipefail; $1" bash "${args[@]}"
}
same_as_local() {
    for f in $(seq -f %04g "$1" "$2"); do
        cmp -s -i 57 "$out/local/p.$f.vdb" "$out/farm/p.$f.vdb" || {
            echo "frame $f differs from the local bake"
            exit 1
        }
    done
}
