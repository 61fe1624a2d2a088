# SPDX-License-Identifier: Apache-2.0
# Cross-building cylscan for 64-bit ARM (Debian arm64) with Debian's
# g++-aarch64-linux-gnu and a sysroot from toolchain/make-sysroot.sh:
#   cmake --preset aarch64          (CYLSCAN_SYSROOT: the sysroot, see CMakePresets.json)
# or cmake -DCMAKE_TOOLCHAIN_FILE=toolchain/aarch64-linux-gnu.cmake -DCYLSCAN_SYSROOT=DIR ...
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CYLSCAN_CROSS_TRIPLET aarch64-linux-gnu)
set(CYLSCAN_CROSS_ARCH aarch64)
set(CYLSCAN_CROSS_QEMU qemu-aarch64)
include("${CMAKE_CURRENT_LIST_DIR}/cross-common.cmake")
