#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# A .deb's Depends as a list for mmdebstrap --include: the names, without
# versions, and bookworm-backports as the suite of the two libraries that
# come from there (libgpiod 2, libcamera 0.3).
#   toolchain/deb-depends.sh DEB   ->  libc6,libgpiod3/bookworm-backports,...
set -euo pipefail
dpkg-deb -f "$1" Depends | tr ',' '\n' | sed -e 's/(.*)//' -e 's/ //g' | grep -v '^$' |
  sed -e 's|^libgpiod3$|libgpiod3/bookworm-backports|' -e 's|^libcamera0.3$|libcamera0.3/bookworm-backports|' |
  sort | paste -sd, -
