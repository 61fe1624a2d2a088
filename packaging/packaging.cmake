# SPDX-License-Identifier: Apache-2.0
# Install rules for what the package puts on the target besides the programs
# (board profiles, the root filesystem overlay) and the CPack configuration of
# the Debian package cylscan_<version>_<arch>.deb:
#   cmake --build BUILD && (cd BUILD && cpack -G DEB)
# The programs install themselves (tools/, firmware/daemon/, web/). Paths
# follow the package's layout, prefix /usr: the overlay's files (unit, udev
# rules, tmpfiles, sysusers, /etc/cylscan/cylscan.toml) go to the absolute
# system paths systemd and udev read, whatever the prefix.
include(GNUInstallDirs)

# Board profiles: /usr/share/cylscan/board/<name>/ (board.toml, README, overlays, sim's head and scenes).
# A build without the virtual head (CYLSCAN_WITH_SIM) would refuse sim and sim360: not shipped.
set(cylscan_board_filter)
set(cylscan_deb_boards "virtual head, ")
if(NOT CYLSCAN_WITH_SIM)
  set(cylscan_board_filter REGEX "/board/sim(360)?$" EXCLUDE)
  set(cylscan_deb_boards "")
endif()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/board/ DESTINATION ${CMAKE_INSTALL_DATADIR}/cylscan/board
        ${cylscan_board_filter})
# The overlay, mirrored from rootfs-overlay/ onto /.
if(CYLSCAN_WITH_SIM)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/rootfs-overlay/ DESTINATION /
          PATTERN README.md EXCLUDE)
else()
  # Without the virtual head the daemon's configuration names no board: the
  # installer sets one, and cylscand refuses to start until then, saying so.
  set(cylscan_conf_src ${PROJECT_SOURCE_DIR}/rootfs-overlay/etc/cylscan/cylscan.toml)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${cylscan_conf_src})
  file(READ ${cylscan_conf_src} cylscan_conf)
  string(REGEX REPLACE "\n(board = \"/usr/share/cylscan/board/)sim\"\n"
         "\n# The virtual head is not in this build: set your board's.\n# \\1rpi5\"\n"
         cylscan_conf_off "${cylscan_conf}")
  if(cylscan_conf_off STREQUAL cylscan_conf)
    message(FATAL_ERROR "${cylscan_conf_src}: no 'board = \".../board/sim\"' line to comment out")
  endif()
  file(CONFIGURE OUTPUT ${PROJECT_BINARY_DIR}/packaging/cylscan.toml CONTENT "${cylscan_conf_off}"
       @ONLY)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/rootfs-overlay/ DESTINATION /
          PATTERN README.md EXCLUDE PATTERN cylscan.toml EXCLUDE)
  install(FILES ${PROJECT_BINARY_DIR}/packaging/cylscan.toml DESTINATION /etc/cylscan)
endif()
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
# The licences of cylscan and of what it bundles and links, machine-readable
# (DEP-5), where Debian keeps a package's: /usr/share/doc/cylscan/copyright.
install(FILES ${PROJECT_SOURCE_DIR}/packaging/debian/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR})

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME cylscan)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_PACKAGE_DESCRIPTION
    "cylscan drives a 360-degree fringe-projection 3D scanning head (a cylindrical\n"
    "projector on a stepper rotation stage, triggered cameras) on embedded Linux:\n"
    "the cylscan command line, the cylscand daemon with its HTTP API and web page,\n"
    "board profiles (${cylscan_deb_boards}Raspberry Pi 4/5, generic arm64, emulated board)\n"
    "and a hardened systemd unit.")
string(REPLACE ";" "" CPACK_PACKAGE_DESCRIPTION "${CPACK_PACKAGE_DESCRIPTION}")
set(CYLSCAN_PACKAGE_MAINTAINER "cylscan maintainers <cylscan@localhost>"
    CACHE STRING "Maintainer field of the Debian package")
set(CPACK_PACKAGE_CONTACT "${CYLSCAN_PACKAGE_MAINTAINER}")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)

# The Debian architecture of the target (a cross build packages for its target).
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
  set(cylscan_deb_arch arm64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^arm")
  set(cylscan_deb_arch armhf)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  set(cylscan_deb_arch amd64)
else()
  execute_process(COMMAND dpkg --print-architecture OUTPUT_VARIABLE cylscan_deb_arch
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
endif()
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${cylscan_deb_arch})
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # cylscan_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "")

# Depends: what the binaries link, from dpkg-shlibdeps, plus what the
# maintainer scripts run (groupadd/useradd). A cross build reads the target's
# libraries and their packages' shlibs/symbols files from its sysroot.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
if(CMAKE_CROSSCOMPILING)
  if(NOT CYLSCAN_SYSROOT OR NOT EXISTS "${CYLSCAN_SYSROOT}/.cylscan-dpkg/status")
    message(FATAL_ERROR "A cross package reads its Depends from the sysroot's dpkg database, and "
                        "${CYLSCAN_SYSROOT} has none: remake it with toolchain/make-sysroot.sh.")
  endif()
  # dpkg-shlibdeps finds the target's libraries in the sysroot, objdumps them
  # with the target's binutils (DEB_HOST_ARCH) and maps them to packages with
  # the database toolchain/sysroot-dpkg-db.sh made (DPKG_ADMINDIR): set in
  # cpack's environment by packaging/cpack-project-config.cmake.
  set(CPACK_CYLSCAN_SYSROOT "${CYLSCAN_SYSROOT}")
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS
      "${CYLSCAN_SYSROOT}/lib/${CMAKE_LIBRARY_ARCHITECTURE}"
      "${CYLSCAN_SYSROOT}/usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}")
  set(CPACK_PROJECT_CONFIG_FILE "${PROJECT_SOURCE_DIR}/packaging/cpack-project-config.cmake")
endif()
set(CPACK_DEBIAN_PACKAGE_DEPENDS "passwd")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "systemd, udev")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${PROJECT_SOURCE_DIR}/packaging/debian/postinst
    ${PROJECT_SOURCE_DIR}/packaging/debian/prerm
    ${PROJECT_SOURCE_DIR}/packaging/debian/postrm
    ${PROJECT_SOURCE_DIR}/packaging/debian/conffiles)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
