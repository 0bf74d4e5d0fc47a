#!/usr/bin/env bash
# Configures and builds a tree; extra CMake arguments pass through (they come last, so
# -DCUTSIM_ARCH=portable makes a binary for any x86-64 machine). Release trees are built for this
# machine's CPU (CUTSIM_ARCH=native): they run where they are built, and the step's kernels are
# written for wide vector registers (docs/build.md compares the step's speed).
#   scripts/build.sh [ARGS]          Release in build/: every target (the cutsim program, the tests,
#                                    the benchmarks, the baselines, the Python module)
#   scripts/build.sh --demo [ARGS]   Release in build/: the cutsim program only (scripts/demo.sh)
#   scripts/build.sh --asan [ARGS]   ASan+UBSan in build-asan/: the test programs (not the stress
#                                    ones, which scripts/test.sh does not run there) and the cutsim
#                                    program; -g1, the line tables the sanitizers' stack traces need
set -euo pipefail
cd "$(dirname "$0")/.."
B=build
type=(-DCMAKE_BUILD_TYPE=Release -DCUTSIM_ARCH=native)
all=(-DCUTSIM_TESTS=ON -DCUTSIM_BENCH=ON -DCUTSIM_PYTHON=ON -DCUTSIM_BASELINES=ON)
targets=()
case "${1:-}" in
  --demo)
    shift
    all=(-DCUTSIM_TESTS=OFF -DCUTSIM_BENCH=OFF -DCUTSIM_PYTHON=OFF -DCUTSIM_BASELINES=OFF)
    targets=(--target cutsim) ;;
  --asan)
    shift
    B=build-asan
    type=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DCUTSIM_SANITIZE=ON)
    all=(-DCUTSIM_TESTS=ON -DCUTSIM_STRESS=OFF -DCUTSIM_BENCH=OFF -DCUTSIM_PYTHON=OFF -DCUTSIM_BASELINES=OFF) ;;
esac
# Ninja for a new build folder when it is installed (an existing folder keeps its generator)
gen=()
if [ ! -f "$B/CMakeCache.txt" ] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
cmake -S . -B "$B" "${gen[@]}" "${type[@]}" "${all[@]}" "$@" >/dev/null
cmake --build "$B" "${targets[@]}" -j"$(nproc)"
