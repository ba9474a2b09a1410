#!/usr/bin/env bash
# The unit and integration tests built with clang's address and undefined-
# behaviour sanitizers (and libFuzzer's coverage, so that tools/fuzz.sh uses
# the same build), in build-fuzz/.  Installs clang's runtime if missing.
#   bash tools/sanitize.sh          build, then run the tests
#   bash tools/sanitize.sh build    build only
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${CAMBIUM_FUZZ_BUILD_DIR:-$root/build-fuzz}
# The project's Debian packages, and clang with its sanitizer and fuzzer
# runtimes and its linker.
CAMBIUM_EXTRA_PACKAGES="clang-14 libclang-rt-14-dev lld" bash "$root/tools/setup.sh" packages

if [ ! -f "$build/CMakeCache.txt" ]; then
  # -O1 and line tables only: a third less to compile than -O2 -g, and
  # sanitizer reports still name files and lines.
  CC=clang-14 CXX=clang++-14 cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=None \
    -DCMAKE_C_FLAGS="-O1 -gline-tables-only" -DCMAKE_CXX_FLAGS="-O1 -gline-tables-only" \
    -DCAMBIUM_SANITIZE=ON -DCAMBIUM_FUZZ=ON
fi
# Only what the tests below and tools/fuzz.sh run: not the kernel tests nor
# the benchmarks' peer programs.
cmake --build "$build" -j"$(nproc)" --target unit_and_integration_tests fuzzers
[ "${1:-test}" = build ] && exit 0

# Every report is fatal; leaks are not checked (OpenCL drivers keep theirs
# until exit).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=0:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:suppressions=$root/tests/sanitizers/ubsan.supp}
# Two tests are left to the release run: their time is the field evaluator's
# throughput over millions of samples (a 50-frame sequence; a brute-force
# surface four times finer than the voxels), 5 of the 12 minutes here, and
# the code they run, the lighter tests run too.
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" -L 'unit|integration' \
  -E '^(Sequence\.VolumeChangesSmoothlyFromFrameToFrame|BakeCompleteness\.NoBandVoxelMissingAndNoneOutside)$'
