#!/usr/bin/env bash
# Runs every libFuzzer harness (tests/fuzz) for SECONDS each (default 60) on
# the sanitized clang build (tools/sanitize.sh build), from a seed corpus of
# examples/, tests/fuzz/seeds/ and tests/fuzz/regressions/, and prints what
# each reached.  A finding stops with a non-zero status and leaves the input
# in build-fuzz/findings/<harness>/: keep it in tests/fuzz/regressions/.
# --ci replays the seeds and the kept regressions through each harness, no
# mutation: the same inputs every run, so that CI's verdict depends on the
# code alone.  A fixed-seed exploration is not the same inputs every run:
# the readers' coverage differs between runs of one input (the photo
# harness's seeds reached 772 or 773 edges in six runs), and libFuzzer's
# mutations follow the coverage; CI once failed on an input that local runs
# from the same seed never reached (docs/testing.md).  Explore with a timed
# run (SECONDS) when a reader changes and keep what it finds.  A finding's
# log tail and its bytes are printed.
#   bash tools/fuzz.sh [SECONDS | --ci]
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${CAMBIUM_FUZZ_BUILD_DIR:-$root/build-fuzz}
ci=false
if [ "${1:-}" = --ci ]; then
  ci=true
else
  seconds=${1:-60}
fi

bash "$root/tools/sanitize.sh" build
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:suppressions=$root/tests/sanitizers/ubsan.supp}

# Seeds the harnesses cannot find in the tree: a small .vdb and its meshes
# (the mesh harness reads a leading byte: even for OBJ, odd for PLY).
made=$build/fuzz-made-seeds
if [ ! -f "$made/small.vdb" ]; then
  mkdir -p "$made"
  "$build/cambium" bake "$root/examples/sphere_and_cone.json" --voxel-size 0.25 --device cpu \
    -o "$made/small.vdb" >/dev/null
  "$build/cambium" mesh "$made/small.vdb" -o "$made/small.obj" >/dev/null
  "$build/cambium" mesh "$made/small.vdb" -o "$made/small.ply" >/dev/null
  { printf '\0'; cat "$made/small.obj"; } >"$made/obj.mesh"
  { printf '\1'; cat "$made/small.ply"; } >"$made/ply.mesh"
fi

seeds() {
  case $1 in
    scene) ls "$root"/examples/*.json ;;
    lsystem) ls "$root"/examples/lsystems/*.l ;;
    growth) ls "$root"/examples/populus/*.json ;;
    shape) ls "$root"/examples/shapes/*.json ;;
    mesh) ls "$made"/*.mesh ;;
    vdb | signedvdb) ls "$made"/small.vdb ;;
  esac
  for kind in seeds regressions; do
    [ -d "$root/tests/fuzz/$kind/$1" ] && find "$root/tests/fuzz/$kind/$1" -type f ! -name '.*'
  done
  return 0
}

# One harness: its line of the report in $build/fuzz-<harness>.result.
fuzz_one() {
  local h=$1 corpus=$build/corpus/$1 findings=$build/findings/$1 log=$build/fuzz-$1.log
  local limit=(-max_total_time="${seconds:-0}")
  if $ci; then
    corpus=$build/corpus-ci/$h
    rm -rf "$corpus"
    limit=(-runs=0)
  fi
  mkdir -p "$corpus" "$findings"
  for s in $(seeds "$h"); do cp -n "$s" "$corpus/" 2>/dev/null || true; done
  local result=clean start=$SECONDS
  if ! "$build/tests/fuzz/fuzz_$h" "$corpus" "${limit[@]}" -timeout=10 -rss_limit_mb=3000 \
      -malloc_limit_mb=2500 -print_final_stats=1 -artifact_prefix="$findings/" >"$log" 2>&1; then
    result="FINDING: $(ls "$findings" | head -1) (see $log)"
  fi
  local took=$((SECONDS - start > 0 ? SECONDS - start : 1))
  local execs last cov ft corp
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  last=$(grep -E '^#[0-9]+' "$log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' <<<"$last" | grep -o '[0-9]*' || echo 0)
  ft=$(grep -o 'ft: [0-9]*' <<<"$last" | grep -o '[0-9]*' || echo 0)
  corp=$(grep -o 'corp: [0-9]*' <<<"$last" | grep -o '[0-9]*' || echo 0)
  printf '%-9s %8s %12s %10s %6s %7s %6s  %s\n' "$h" "$took" "$execs" "$((execs / took))" "$cov" "$ft" \
    "$corp" "$result" >"$build/fuzz-$h.result"
}

# The harnesses run one per core at a time (each is one thread): 10 of them
# for 30 s take under 3 min on two cores, not 5.
# (The harnesses are those tests/fuzz/CMakeLists.txt builds: one list.)
harnesses=()
for f in "$build"/tests/fuzz/fuzz_*; do
  [ -f "$f" ] && [ -x "$f" ] && harnesses+=("${f##*/fuzz_}")
done
[ ${#harnesses[@]} -gt 0 ] || { echo "no fuzz harnesses in $build/tests/fuzz" >&2; exit 1; }
for h in "${harnesses[@]}"; do
  rm -f "$build/fuzz-$h.result"
  while [ "$(jobs -rp | wc -l)" -ge "$(nproc)" ]; do wait -n || true; done
  fuzz_one "$h" &
done
wait

report=$build/fuzz-report.txt
printf '%-9s %8s %12s %10s %6s %7s %6s  %s\n' harness seconds executions exec/s cov features corpus result | tee "$report"
status=0
for h in "${harnesses[@]}"; do
  if [ -f "$build/fuzz-$h.result" ]; then
    tee -a "$report" <"$build/fuzz-$h.result"
    if grep -q FINDING "$build/fuzz-$h.result"; then
      status=1
      # What a CI log must carry to reproduce it: the report and the input.
      { echo "== $h: the end of $build/fuzz-$h.log"
        grep -v '^#[0-9]' "$build/fuzz-$h.log" | tail -40
        for f in "$build/findings/$h"/*; do
          echo "== $h: $f ($(stat -c %s "$f") bytes), its first 4 KB"
          head -c 4096 "$f" | od -A d -t x1
        done; } >&2
    fi
  else
    echo "$h: the harness's run ended without a report (see $build/fuzz-$h.log)" | tee -a "$report"
    status=1
  fi
done
exit $status
