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
# Part 2 (issue 15): blending, the shader, animation.
picture rusted_fuse --width 640 --height 480 --camera "look:4.5,-2.2,2.6:0,0,1.4:38"
picture planet --width 640 --height 480 --camera "look:0,0.4,3.4:0,0,0:38"
picture tree_blend_sharp "${tree[@]}"
picture tree_blend_soft "${tree[@]}"
# The tentacle creature at frames 1, 12 and 24: its tentacles grow and turn.
"$cambium" shape "$here/tentacle_creature.json" --frames 1-24:11 -o "$out/creature.####.vdb"
for f in 0001 0012 0023; do
  "$cambium" render "$out/creature.$f.vdb" -o "$out/creature.$f.png" --spp 4 --width 400 --height 400
done
oiiotool "$out/creature.0001.png" "$out/creature.0012.png" "$out/creature.0023.png" --mosaic 3x1 \
  -o "$root/docs/images/shape_tentacle_creature.png"
