#!/usr/bin/env bash
# The pictures of docs/shape-synthesis.md: every example of this folder
# synthesised, baked into a level set and rendered with cambium render.
#   bash examples/shapes/make_images.sh [BUILD_DIR]   (default: build)
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../.." && pwd)
cambium=${1:-$root/build}/cambium
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
picture() {  # NAME [render options...]
  local name=$1
  shift
  "$cambium" shape "$here/$name.json" -o "$out/$name.vdb"
  "$cambium" render "$out/$name.vdb" -o "$root/docs/images/shape_$name.png" --spp 4 "$@"
}
for name in rock berry tentacles mine mushroom_planet spurs_level1 spurs_level3 spurs_both fuse; do
  picture "$name" --width 640 --height 480
done
tree=(--width 480 --height 720 --camera "look:2.2,1.2,3.0:0.1,0.85,0:32")
picture tree_captured "${tree[@]}"
picture tree_edit "${tree[@]}"
