#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz: tet-mesh readers, surface readers, the scene loader,
# --set) with clang, ASan and UBSan in build-fuzz, and runs each for a budget.
#   scripts/fuzz.sh                 10 minutes per target
#   scripts/fuzz.sh SECONDS         SECONDS per target
#   scripts/fuzz.sh --build-only    build, run nothing
#   scripts/fuzz.sh --release ...   the same without sanitizers, optimised (-O2, NDEBUG), in
#                                   build-fuzz-release: the code as Release runs it, faster
# Findings (crash-*, timeout-*, oom-* inputs) land in BUILD/tests/fuzz/long_TARGET/; a
# summary line per target gives executions, corpus size and the result.
set -euo pipefail
cd "$(dirname "$0")/.."
B=build-fuzz
# -O1 -g1: the sanitizers make -O2 compile much longer (docs/build.md, where the build time goes)
config=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DCUTSIM_FUZZ_SANITIZE=ON)
if [ "${1:-}" = --release ]; then
  B=build-fuzz-release
  config=(-DCMAKE_BUILD_TYPE=Release -DCUTSIM_FUZZ_SANITIZE=OFF)
  shift
fi
budget=600
build_only=0
case "${1:-}" in
  --build-only) build_only=1 ;;
  "") ;;
  *[!0-9]*) echo "usage: scripts/fuzz.sh [--release] [SECONDS | --build-only]" >&2; exit 2 ;;
  *) budget=$1 ;;
esac
gen=()
if [ ! -f "$B/CMakeCache.txt" ] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
cmake -S . -B "$B" "${gen[@]}" -DCMAKE_CXX_COMPILER=clang++ "${config[@]}" -DCUTSIM_FUZZ=ON >/dev/null
cmake --build "$B" -j"$(nproc)"
[ "$build_only" = 1 ] && exit 0
data=$(sed -n 's/^CUTSIM_DATA_DIR:PATH=//p' "$B/CMakeCache.txt")
declare -A seeds=(
  [tet_mesh]="assets/meshes $data/tet $data/broken"
  [surface]="assets/meshes $data/surface $data/broken"
  [scene]="assets/scenes"
  [set]="tests/fuzz/seeds/set")
status=0
for t in tet_mesh surface scene set; do
  work=$B/tests/fuzz/long_$t
  log=$work.log
  # shellcheck disable=SC2086
  if tests/fuzz/run.sh "$PWD/$B/tests/fuzz/fuzz_$t" "$PWD/$work" -max_total_time="$budget" -- ${seeds[$t]} >"$log" 2>&1; then
    result=ok
  else
    result="FINDING (see $log)"
    status=1
  fi
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  corpus=$(find "$work/corpus" -type f | wc -l)
  echo "fuzz_$t: ${budget} s, ${execs:-?} executions, $corpus new corpus inputs: $result"
done
exit $status
