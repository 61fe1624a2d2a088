# SPDX-License-Identifier: Apache-2.0
# Cross-building cylscan for 32-bit ARM with hardware floating point (Debian
# armhf) with Debian's g++-arm-linux-gnueabihf and a sysroot from
# toolchain/make-sysroot.sh:
#   cmake --preset armhf            (CYLSCAN_SYSROOT: the sysroot, see CMakePresets.json)
# or cmake -DCMAKE_TOOLCHAIN_FILE=toolchain/arm-linux-gnueabihf.cmake -DCYLSCAN_SYSROOT=DIR ...
set(CMAKE_SYSTEM_PROCESSOR armv7l)
set(CYLSCAN_CROSS_TRIPLET arm-linux-gnueabihf)
set(CYLSCAN_CROSS_ARCH armhf)
set(CYLSCAN_CROSS_QEMU qemu-arm)
# GCC 7.1 changed how ARM passes some std::map iterators, and GCC notes it at
# every such call (about a hundred in this build); the notes concern linking
# with code built by GCC older than 7.1, which nothing here is.
set(CMAKE_CXX_FLAGS_INIT "-Wno-psabi")
include("${CMAKE_CURRENT_LIST_DIR}/cross-common.cmake")
