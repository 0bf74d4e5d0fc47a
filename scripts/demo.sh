#!/usr/bin/env bash
# The default demo: installs what is missing, builds, and analyses the liver's stable time step
# (table on the terminal, per-element fields in captures/demo/liver_dt.vtu, report in
# captures/demo/report.json).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
DATA="${CUTSIM_DATA:-../shared/data}"
mkdir -p captures/demo
build/cutsim dt "$DATA/tet/sofa_liver.msh" --scale 0.0254 --worst 10 --vtu captures/demo/liver_dt.vtu
build/cutsim dt "$DATA/tet/sofa_liver.msh" --scale 0.0254 --worst 10 --json > captures/demo/report.json
echo "wrote captures/demo/liver_dt.vtu and captures/demo/report.json"
