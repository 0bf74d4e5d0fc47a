#!/usr/bin/env bash
# Formats every C++ file of the project with .clang-format; --check only reports files that differ
# (exit 1), which the test suite runs.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=(-i)
[ "${1:-}" = --check ] && mode=(--dry-run --Werror)
cf=$(command -v clang-format-14 || command -v clang-format || true)
[ -n "$cf" ] || { echo "error: clang-format not found (apt-get install clang-format)" >&2; exit 2; }
dirs=()
for d in app bench physics render tests python examples; do [ -d "$d" ] && dirs+=("$d"); done
find "${dirs[@]}" \( -name '*.cpp' -o -name '*.hpp' \) -print0 | sort -z | xargs -0 "$cf" "${mode[@]}"
