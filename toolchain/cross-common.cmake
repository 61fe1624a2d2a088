# SPDX-License-Identifier: Apache-2.0
# Shared by toolchain/aarch64-linux-gnu.cmake and toolchain/arm-linux-gnueabihf.cmake,
# which set CYLSCAN_CROSS_TRIPLET, CYLSCAN_CROSS_ARCH (make-sysroot's name) and
# CYLSCAN_CROSS_QEMU before including it.
#
# Compilers: Debian's cross compilers (toolchain/install-cross.sh). Libraries and
# headers: a sysroot made by toolchain/make-sysroot.sh, given as the cache
# variable CYLSCAN_SYSROOT or the environment variable of the same name.
# Test programs run under qemu-user with -L at that sysroot, so ctest runs them.
# No -march/-mfpu: the compilers' Debian defaults (armv8-a with NEON for arm64,
# armv7-a with VFPv3-D16 for armhf) run on every board of the architecture.
set(CMAKE_SYSTEM_NAME Linux)

set(CMAKE_C_COMPILER ${CYLSCAN_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${CYLSCAN_CROSS_TRIPLET}-g++)

if(NOT CYLSCAN_SYSROOT AND DEFINED ENV{CYLSCAN_SYSROOT})
  set(CYLSCAN_SYSROOT "$ENV{CYLSCAN_SYSROOT}")
endif()
if(NOT CYLSCAN_SYSROOT)
  message(FATAL_ERROR "Cross-building for ${CYLSCAN_CROSS_TRIPLET} needs a sysroot: make one with "
                      "'toolchain/make-sysroot.sh ${CYLSCAN_CROSS_ARCH} DIR' and pass "
                      "-DCYLSCAN_SYSROOT=DIR (or set the environment variable CYLSCAN_SYSROOT).")
endif()
get_filename_component(CYLSCAN_SYSROOT "${CYLSCAN_SYSROOT}" ABSOLUTE)
if(NOT EXISTS "${CYLSCAN_SYSROOT}/usr/include/${CYLSCAN_CROSS_TRIPLET}")
  message(FATAL_ERROR "CYLSCAN_SYSROOT=${CYLSCAN_SYSROOT} is not a ${CYLSCAN_CROSS_TRIPLET} sysroot "
                      "(no usr/include/${CYLSCAN_CROSS_TRIPLET}): make it with "
                      "'toolchain/make-sysroot.sh ${CYLSCAN_CROSS_ARCH} ${CYLSCAN_SYSROOT}'.")
endif()
set(CYLSCAN_SYSROOT "${CYLSCAN_SYSROOT}" CACHE PATH "Sysroot of the cross build (toolchain/make-sysroot.sh)")
# try_compile projects read this file again: give them the sysroot too.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES CYLSCAN_SYSROOT)

set(CMAKE_SYSROOT "${CYLSCAN_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${CYLSCAN_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)  # build tools are the host's
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# pkg-config (the host's) reads only the target's .pc files and prefixes
# their paths with the sysroot.
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${CYLSCAN_SYSROOT}")
set(ENV{PKG_CONFIG_LIBDIR}
    "${CYLSCAN_SYSROOT}/usr/lib/${CYLSCAN_CROSS_TRIPLET}/pkgconfig:${CYLSCAN_SYSROOT}/usr/lib/pkgconfig:${CYLSCAN_SYSROOT}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")

# qemu-user with -L at the same sysroot: the target's loader with the target's
# libc (pairing the cross toolchain's loader with another libc hangs programs
# that fork, and libcamera's tracing forks before main).
find_program(CYLSCAN_QEMU_USER ${CYLSCAN_CROSS_QEMU})
if(CYLSCAN_QEMU_USER)
  set(CMAKE_CROSSCOMPILING_EMULATOR "${CYLSCAN_QEMU_USER};-L;${CYLSCAN_SYSROOT}")
else()
  message(WARNING "${CYLSCAN_CROSS_QEMU} not found (Debian package qemu-user): the "
                  "${CYLSCAN_CROSS_TRIPLET} test programs cannot run on this host.")
endif()
