#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Makes a Debian bookworm sysroot for cross-building cylscan:
#   toolchain/make-sysroot.sh aarch64|armhf DIR
# The target's -dev packages (and what they depend on) are unpacked into DIR
# with `mmdebstrap --variant=extract`: no maintainer scripts run and the host's
# dpkg is left alone (multiarch -dev packages would have to match the host's
# versions, and OpenCV's and libcamera's cannot be co-installed with amd64's).
# The libgpiod v2 and libcamera 0.3 packages come from bookworm-backports, as
# on the host (scripts/install-deps.sh).
#
# A dpkg database of the unpacked packages, for dpkg-shlibdeps, is made in
# DIR/.cylscan-dpkg (toolchain/sysroot-dpkg-db.sh).
#
# DIR is reused when its stamp says it was made from the same package list, so
# a cached sysroot (build/sysroot-<arch>) costs nothing the second time.
# The Debian mirror is the one the host's apt uses for bookworm; set
# CYLSCAN_DEBIAN_MIRROR to override it.
set -euo pipefail

usage() { echo "usage: $0 aarch64|armhf DIR" >&2; exit 2; }
[ "$#" -eq 2 ] || usage
case "$1" in
  aarch64) debarch=arm64; triplet=aarch64-linux-gnu ;;
  armhf) debarch=armhf; triplet=arm-linux-gnueabihf ;;
  *) usage ;;
esac
dir=$2

# What the build links (top-level, drivers/ and tests/ CMakeLists) and what
# find_package needs to see: OpenCV's CMake config is in libopencv-dev and it
# checks every module's library exists, so the whole of it is needed.
packages=(
  libc6-dev libstdc++-12-dev linux-libc-dev
  libopencv-dev libeigen3-dev nlohmann-json3-dev libtomlplusplus-dev libcli11-dev
  libmicrohttpd-dev libsystemd-dev libcurl4-openssl-dev libturbojpeg0-dev libpng-dev libtiff-dev zlib1g-dev
  libgtest-dev libgmock-dev
  libgpiod-dev/bookworm-backports libcamera-dev/bookworm-backports
)
stamp="$dir/.cylscan-sysroot"
want="$debarch ${packages[*]} +dpkg-db"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -s "$dir/.cylscan-dpkg/status" ]; then
  echo "make-sysroot: $dir is up to date ($debarch)"
  exit 0
fi

mirror=${CYLSCAN_DEBIAN_MIRROR:-}
if [ -z "$mirror" ]; then
  mirror=$(apt-get indextargets --format '$(RELEASE) $(SITE)' 'Identifier: Packages' 2>/dev/null |
    awk '$1 == "bookworm" { print $2; exit }')
fi
if [ -z "$mirror" ]; then
  echo "make-sysroot: no bookworm source in the host's apt configuration; set CYLSCAN_DEBIAN_MIRROR" >&2
  exit 1
fi

mode=root
if [ "$(id -u)" -ne 0 ]; then mode=unshare; fi
rm -rf "$dir"
mkdir -p "$(dirname "$dir")"
include=$(IFS=,; echo "${packages[*]}")
here=$(cd "$(dirname "$0")" && pwd)
# The extract hook (the one hook the extract variant runs) sees the .debs in the apt
# cache: it registers them in a dpkg database for dpkg-shlibdeps.
mmdebstrap --mode="$mode" --arch="$debarch" --variant=extract --include="$include" \
  --skip=cleanup/apt/lists \
  --extract-hook="\"$here/sysroot-dpkg-db.sh\" \"\$1\" \"\$1\"/var/cache/apt/archives/*.deb" \
  bookworm "$dir" \
  "deb $mirror bookworm main" "deb $mirror bookworm-updates main" \
  "deb $mirror bookworm-backports main"

# The BLAS/LAPACK alternatives a maintainer script would have made.
"$here/blas-alternatives.sh" "$dir/usr/lib/$triplet"
echo "$want" >"$stamp"
echo "make-sysroot: $dir ready ($debarch, $(du -sh "$dir" | cut -f1))"
