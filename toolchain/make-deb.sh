#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The arm64 package, built in BUILD_DIR against SYSROOT (toolchain/make-sysroot.sh):
# only the package's programs (and any EXTRA_TARGET) are built, with the
# virtual head (board/sim is in the package) and without the page's build.
# A build directory that scripts/cross-test.sh made is reused: its objects
# are the same. Prints the .deb's path last.
#   toolchain/make-deb.sh BUILD_DIR SYSROOT [EXTRA_TARGET...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dir=$(realpath -m "$1")
sysroot=$(realpath -m "$2")
shift 2
cd "$root"
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake --preset aarch64 -B "$dir" "${launcher[@]}" -DCYLSCAN_SYSROOT="$sysroot" \
  -DCYLSCAN_BUILD_TESTS=ON -DCYLSCAN_BUILD_WEB=OFF -DCYLSCAN_WITH_SIM=ON \
  -DCMAKE_SKIP_INSTALL_ALL_DEPENDENCY=ON >/dev/null
cmake --build "$dir" -j"$(nproc)" --target cylscan cylscand "$@"
rm -f "$dir"/package/cylscan_*_arm64.deb
(cd "$dir" && cpack -G DEB -B "$dir/package" >/dev/null)
ls "$dir"/package/cylscan_*_arm64.deb
