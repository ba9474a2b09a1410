#!/usr/bin/env bash
# The pictures of docs/bark.md: the Populus example's bark, close up and whole,
# a short sequence of the trunk showing the pattern stays with the wood, and the
# colours of a photo.  No photo ships with cambium: this script makes a
# bark-like one with oiiotool (grey noise tinted brown).
#   bash examples/populus/make_bark_images.sh [BUILD_DIR]   (default: build)
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../.." && pwd)
cambium=${1:-$root/build}/cambium
img=$root/docs/images
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
oiiotool --pattern noise:type=gaussian:mean=0.4:stddev=0.15 256x256 1 --ch Y,Y,Y \
  --chnames R,G,B --mulc 0.9,0.8,0.65 -o "$out/bark.png"
close=(--width 480 --height 600 --spp 4 --camera "look:1.2,2.1,1.2:0,1.9,0:32")
"$cambium" bake "$here/populus.json" --no-leaves --voxel-size 0.01 -o "$out/p27.vdb"
"$cambium" render "$out/p27.vdb" -o "$out/close.png" "${close[@]}"
"$cambium" bake "$here/populus.json" --no-leaves --voxel-size 0.01 \
  --bark-photo "$out/bark.png" -o "$out/p27photo.vdb"
"$cambium" render "$out/p27photo.vdb" -o "$out/closephoto.png" "${close[@]}"
oiiotool "$out/close.png" "$out/closephoto.png" --mosaic 2x1 -o "$img/populus_bark_close.png"
"$cambium" render "$out/p27photo.vdb" -o "$img/populus_bark_whole.png" --width 640 --height 800 \
  --spp 4
# Years 14, 20 and 27, the same view of the trunk: the furrows deepen and widen
# with the wood and stay where they are.
for y in 14 20 27; do
  "$cambium" bake "$here/populus.json" --no-leaves --time $y --voxel-size 0.01 -o "$out/s$y.vdb"
  "$cambium" render "$out/s$y.vdb" -o "$out/s$y.png" --width 360 --height 480 --spp 4 \
    --camera "look:1.0,1.5,1.0:0,1.4,0:30"
done
oiiotool "$out/s14.png" "$out/s20.png" "$out/s27.png" --mosaic 3x1 -o "$img/populus_bark_years.png"
