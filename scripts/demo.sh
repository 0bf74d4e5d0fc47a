#!/usr/bin/env bash
# The default demo: installs the packages it needs, builds the cutsim program (nothing else),
# prints the liver's stable time-step table, then runs assets/scenes/demo.json: frames, video,
# report and final mesh in captures/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh demo
scripts/build.sh --demo
build/cutsim dt assets/meshes/liver.msh --scale 0.0254 --worst 5
build/cutsim run assets/scenes/demo.json --out captures/demo
echo "captures/demo: report.json, final.vtu, frames/, video.mp4 (when ffmpeg is installed)"
