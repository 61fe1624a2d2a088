#!/usr/bin/env bash
# Installs everything cylscan needs to build and test on Debian bookworm (amd64).
# Idempotent; needs root (or sudo).
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
export DEBIAN_FRONTEND=noninteractive

PKGS=(
  build-essential cmake ninja-build pkg-config git
  libopencv-dev            # imgcodecs (PNG/TIFF), imgproc, calib3d
  libeigen3-dev            # small dense solvers
  nlohmann-json3-dev       # capture.json, --json output
  libtomlplusplus-dev      # scene and board TOML
  libcli11-dev             # the cylscan command line
  libgtest-dev libgmock-dev
  libbenchmark-dev
)

missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
