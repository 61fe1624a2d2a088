#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs what cross-building cylscan for ARM needs on a Debian bookworm host:
# Debian's cross compilers (arm64 and armhf), qemu-user to run the ARM test
# programs, mmdebstrap to make the target's sysroot (toolchain/make-sysroot.sh).
# The target's libraries come from that sysroot, not from multiarch packages,
# so the host's own packages are never touched. Idempotent; needs root (or sudo).
#   toolchain/install-cross.sh [aarch64|armhf ...]   (default: both)
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
export DEBIAN_FRONTEND=noninteractive

arches=("$@")
if [ "${#arches[@]}" -eq 0 ]; then arches=(aarch64 armhf); fi

pkgs=(
  mmdebstrap            # the target's sysroot (--variant=extract: no maintainer scripts run)
  qemu-user             # qemu-aarch64 / qemu-arm: CMAKE_CROSSCOMPILING_EMULATOR for ctest
  debian-archive-keyring # mmdebstrap checks the target's Release files with it
  pkg-config cmake ninja-build
)
for a in "${arches[@]}"; do
  case "$a" in
    aarch64) pkgs+=(g++-aarch64-linux-gnu) ;;
    armhf) pkgs+=(g++-arm-linux-gnueabihf) ;;
    *) echo "install-cross.sh: unknown architecture '$a' (aarch64 or armhf)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
