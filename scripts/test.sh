#!/usr/bin/env bash
# Installs what is missing, builds Release, runs the unit tests, the fuzz targets briefly, then the
# unit tests again under AddressSanitizer + UBSan. Stress tests and benchmarks have their own
# commands (README). Each configuration builds only what it runs: the fuzz build the physics
# library and the fuzz targets, the sanitizer build the test programs and the cutsim program.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
(cd build && ctest -LE stress --output-on-failure -j"$(nproc)" --timeout 900)
# the libFuzzer targets (clang), a fixed number of runs each from a fixed seed
if [ "${CUTSIM_SKIP_FUZZ:-0}" != 1 ]; then
  scripts/fuzz.sh --build-only
  (cd build-fuzz && ctest -L fuzz --output-on-failure -j"$(nproc)")
fi
if [ "${CUTSIM_SKIP_SANITIZE:-0}" != 1 ]; then
  scripts/build.sh --asan
  (cd build-asan && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
     ctest -LE stress --output-on-failure -j"$(nproc)" --timeout 1800)
fi
