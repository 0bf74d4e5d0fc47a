#!/usr/bin/env bash
# Installs the Debian packages cutsim builds and runs with (idempotent; root or sudo).
set -euo pipefail
PKGS=(build-essential cmake pkg-config
      libeigen3-dev libspectra-dev libbullet-dev libtet1.5-dev libgmsh-dev libcgal-dev
      libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri libglfw3-dev libimgui-dev libstb-dev libpng-dev
      nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev
      ffmpeg xvfb xauth gnuplot-nox clang-format
      clang libfuzzer-14-dev libomp-dev
      pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib parallel)
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
