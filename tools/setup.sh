#!/usr/bin/env bash
# cambium setup on Debian 12: installs what is missing (apt-get, as root or
# through sudo), configures and builds, then
#   bash tools/setup.sh run    runs the main job on the bundled default example
#   bash tools/setup.sh test   runs every test through CTest
#   bash tools/setup.sh packages   only installs what is missing
#                                  (and CAMBIUM_EXTRA_PACKAGES)
# Idempotent: with everything present it only checks and rebuilds what changed.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${CAMBIUM_BUILD_DIR:-$root/build}
mode=${1:-run}

packages=(
  build-essential cmake ninja-build pkg-config
  libopenvdb-dev libnanovdb-dev libopenvdb-tools libblosc-dev libboost-iostreams-dev
  libopenimageio-dev openimageio-tools libglm-dev libembree-dev libtbb-dev libosd-dev
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers clinfo
  libgtest-dev libbenchmark-dev nlohmann-json3-dev libcli11-dev libfmt-dev libcpp-httplib-dev
  time ccache
)
# More for a caller's own needs (tools/sanitize.sh: clang and its runtimes).
read -r -a extra <<<"${CAMBIUM_EXTRA_PACKAGES:-}"
packages+=("${extra[@]}")

# install_missing [--no-install-recommends] PACKAGE...: those not installed.
install_missing() {
  local opts=() missing=() p sudo=""
  if [ "${1:-}" = --no-install-recommends ]; then
    opts+=("$1")
    shift
  fi
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  ((${#missing[@]})) || return 0
  echo "cambium setup: installing ${missing[*]}"
  [ "$(id -u)" -eq 0 ] || sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${opts[@]}" "${missing[@]}"
}
install_missing "${packages[@]}"
# The tests' own: a private Slurm cluster (tools/slurm_cluster.sh), without
# the recommended extras (slurm-wlm would pull 35 packages).
if [ "$mode" = test ]; then
  install_missing --no-install-recommends slurmctld slurmd slurm-client munge
  # The preview page's browser test (tests/browser): Debian's chromium, and
  # Node.js with npm where the machine has none (Debian's 18 is enough for
  # playwright-core 1.61).
  install_missing chromium
  command -v npm >/dev/null || install_missing nodejs npm
fi

[ "$mode" = packages ] && exit 0

if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$build" -j"$(nproc)"
# The OpenCL kernels compiled once here, not on the first bake or render.
case "$mode" in run | test | build) "$build/cambium" prepare ;; esac
# playwright-core, as tests/browser/package-lock.json pins it, beside the build.
if [ "$mode" = test ] && ! cmp -s "$root/tests/browser/package-lock.json" "$build/browser/installed.json"; then
  mkdir -p "$build/browser"
  cp "$root/tests/browser/package.json" "$root/tests/browser/package-lock.json" "$build/browser/"
  (cd "$build/browser" && npm ci --no-audit --no-fund --loglevel=error)
  cp "$root/tests/browser/package-lock.json" "$build/browser/installed.json"
fi

case "$mode" in
  run)
    # The default example: a Populus deltoides grown for 27 years (paper 000),
    # baked at one frame a year, the last frame meshed and rendered.
    populus="$root/examples/populus/populus.json"
    "$build/cambium" growth "$populus" --year 27 --print-stats
    mkdir -p "$root/out"
    "$build/cambium" bake "$populus" --frames 1-27 --fps-per-year 1 --voxel-size 0.02 \
      -o "$root/out/populus.####.vdb"
    "$build/cambium" mesh "$root/out/populus.0027.vdb" -o "$root/out/populus.0027.ply"
    "$build/cambium" render "$root/out/populus.0027.vdb" -o "$root/out/populus.0027.png" --spp 4
    ;;
  test)
    ctest --test-dir "$build" --output-on-failure -j"$(nproc)"
    ;;
  build)
    ;;
  *)
    echo "usage: bash tools/setup.sh [run|test|build|packages]" >&2
    exit 64
    ;;
esac
