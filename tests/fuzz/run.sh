#!/usr/bin/env bash
# run.sh FUZZER WORKDIR [libFuzzer flags] -- SEED_DIRS...
# Runs a fuzz target over a fresh copy of its corpus; crash inputs land in WORKDIR. Exits non-zero
# on any finding (crash, leak, timeout over 60 s, out of memory).
set -euo pipefail
fuzzer=$1 work=$2
shift 2
flags=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do flags+=("$1"); shift; done
[ $# -gt 0 ] && shift
seeds=()
for d in "$@"; do [ -d "$d" ] && seeds+=("$(cd "$d" && pwd)"); done  # absolute: the run changes folder
rm -rf "$work"
mkdir -p "$work/corpus"
cd "$work"
exec "$fuzzer" -timeout=60 -rss_limit_mb=4096 -malloc_limit_mb=4096 -print_final_stats=1 \
  -artifact_prefix="$work/" "${flags[@]}" "$work/corpus" "${seeds[@]}"
