# SPDX-License-Identifier: Apache-2.0
# Read by cpack when it runs (CPACK_PROJECT_CONFIG_FILE), for a cross package
# only: dpkg-shlibdeps, which cpack runs, takes the target's architecture and
# the sysroot's dpkg database (toolchain/sysroot-dpkg-db.sh) from its environment.
if(CPACK_CYLSCAN_SYSROOT)
  set(ENV{DEB_HOST_ARCH} "${CPACK_DEBIAN_PACKAGE_ARCHITECTURE}")
  set(ENV{DPKG_ADMINDIR} "${CPACK_CYLSCAN_SYSROOT}/.cylscan-dpkg")
endif()
