#!/usr/bin/env bash
# Where the build time goes: builds TARGET (default cutsim) from scratch in build-times/ without
# ccache, each compiler and linker run timed by /usr/bin/time, and prints the CPU seconds (user +
# sys) of every file, the costliest first, and their total. CPU seconds stay comparable on a busy
# machine, where wall times do not. Extra arguments go to CMake.
#   scripts/build_times.sh [--target TARGET] [CMAKE ARGS]
set -euo pipefail
cd "$(dirname "$0")/.."
target=cutsim
if [ "${1:-}" = --target ]; then target=$2; shift 2; fi
B=build-times
rm -rf "$B"
mkdir -p "$B"
log=$PWD/$B/times.txt
cat > "$B/timed.sh" <<EOS
#!/bin/sh
out=\$(echo "\$@" | sed -n 's/.* -o \([^ ]*\).*/\1/p')
exec /usr/bin/time -a -o "$log" -f "%U %S \$out" "\$@"
EOS
chmod +x "$B/timed.sh"
gen=()
if command -v ninja >/dev/null; then gen=(-G Ninja); fi
cmake -S . -B "$B" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DCUTSIM_CCACHE=OFF \
  -DCMAKE_CXX_COMPILER_LAUNCHER="$PWD/$B/timed.sh" -DCMAKE_CXX_LINKER_LAUNCHER="$PWD/$B/timed.sh" "$@" >/dev/null
cmake --build "$B" --target "$target" -j"$(nproc)" >/dev/null
awk '{printf "%8.1f %s\n", $1 + $2, $3; t += $1 + $2} END {printf "%8.1f total CPU seconds\n", t}' "$log" | sort -rn
