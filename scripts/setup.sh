#!/usr/bin/env bash
# Installs the Debian packages cutsim builds and runs with (idempotent; root or sudo).
#   scripts/setup.sh demo   what scripts/demo.sh needs: the compiler, the libraries of the cutsim
#                           program and ffmpeg
#   scripts/setup.sh        all of it: also the tests, the fuzz targets (clang), the benchmarks,
#                           the Gmsh and CGAL baselines and the Python module
set -euo pipefail
DEMO=(build-essential cmake ninja-build ccache pkg-config
      libeigen3-dev libspectra-dev libbullet-dev libtet1.5-dev
      libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri libglfw3-dev libimgui-dev libstb-dev libdeflate-dev
      nlohmann-json3-dev libcli11-dev ffmpeg)
TEST=(libgmsh-dev libcgal-dev libgtest-dev libgmock-dev libbenchmark-dev
      xvfb xauth gnuplot-nox clang-format
      clang lld libfuzzer-14-dev libomp-dev
      pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib parallel)
case "${1:-all}" in
  demo) PKGS=("${DEMO[@]}") ;;
  all) PKGS=("${DEMO[@]}" "${TEST[@]}") ;;
  *) echo "usage: scripts/setup.sh [demo]" >&2; exit 2 ;;
esac
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "installing: ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
