#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs everything cylscan needs to build and test on Debian bookworm (amd64).
# Idempotent; needs root (or sudo).
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
export DEBIAN_FRONTEND=noninteractive

PKGS=(
  build-essential cmake ninja-build pkg-config git curl
  python3                  # tests/algo/vectorised.py, scripts/lint.sh's clang-tidy groups
  libopencv-dev            # core, imgproc, calib3d (imgcodecs: the tests' own decoder)
  libopenblas0-serial      # tests: OpenCV's LAPACK for the calibration solves, 8x the reference BLAS's speed
  libpng-dev libtiff-dev zlib1g-dev # frames (PNG) and maps (float TIFF), without imgcodecs' GDAL tree
  libeigen3-dev            # small dense solvers
  nlohmann-json3-dev       # capture.json, --json output
  libtomlplusplus-dev      # scene and board TOML
  libcli11-dev             # the cylscan command line
  libmicrohttpd-dev        # cylscand's HTTP API
  libturbojpeg0-dev        # the live view's JPEG frames (TurboJPEG API)
  libsystemd-dev           # cylscand: sd_notify READY/WATCHDOG under systemd
  libcurl4-openssl-dev     # tests: a real HTTP client against the running daemon
  libgtest-dev libgmock-dev
  libbenchmark-dev
  chromium                 # tests/web: the browser test drives Debian's chromium (no browser download)
  mmdebstrap               # tests/packaging: the throwaway root the .deb installs into; toolchain/make-sysroot.sh
  systemd                  # tests/packaging: systemd-analyze verify of the installed unit
  device-tree-compiler     # tests/packaging: the board overlays (board/rpi*/cylscan-pins-overlay.dts) compile
  cppcheck clang-tidy      # scripts/lint.sh: the static analysis CI runs (cppcheck 2.10, clang-tidy 14)
  wrk                      # tests/load: the HTTP load generator of the daemon's load test
  clang libclang-rt-14-dev # scripts/fuzz.sh: the fuzz targets are built with clang, libFuzzer and its sanitizers
  qemu-system-arm dwarves kmod cpio # tests/emulated-board: the arm64 guest, pahole for its modules' BTF, depmod, its initramfs
)
# Hardware backends, from bookworm-backports (bookworm's libgpiod is v1, its
# libcamera 0.0.3): the libgpiod v2 C++ bindings and libcamera 0.3.
# Each with the oldest version that has the API the backends use.
BACKPORTS_PKGS=(
  "libgpiod-dev 2.0"       # GPIO lines (drivers/gpio_gpiod.cpp)
  "libcamera-dev 0.3"      # cameras through libcamera (drivers/camera_libcamera.cpp)
)

installed() {
  dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"
}
# installed PACKAGE MIN_VERSION: installed at MIN_VERSION or later.
installed_at_least() {
  installed "$1" &&
    dpkg --compare-versions "$(dpkg-query -W -f='${Version}' "$1")" ge "$2"
}

updated=0
update_once() {
  if [ "$updated" -eq 0 ]; then
    $SUDO apt-get update -q
    updated=1
  fi
}

# bookworm-backports in apt's sources (its lists updated when it was added).
if [ -n "$(bash "$(dirname "$0")/enable-backports.sh")" ]; then updated=1; fi

missing=()
for p in "${PKGS[@]}"; do
  installed "$p" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  update_once
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

missing=()
for entry in "${BACKPORTS_PKGS[@]}"; do
  read -r p version <<<"$entry"
  installed_at_least "$p" "$version" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  update_once
  $SUDO apt-get install -y -q --no-install-recommends -t bookworm-backports "${missing[@]}"
fi

# The web page is bundled with npm at build time (web/CMakeLists.txt). The
# machines have Node 20 with its own npm: Debian's nodejs/npm only where there
# is no npm at all (Debian's Node 18 bundles the page; playwright-core of the
# browser test wants Node 20).
if ! command -v npm >/dev/null 2>&1; then
  update_once
  $SUDO apt-get install -y -q --no-install-recommends nodejs npm
fi
