#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Adds Debian bookworm-backports to apt's sources (deb822, like the system's
# own) unless some source already names the suite, and updates apt's lists
# when it did. Used by scripts/install-deps.sh (libgpiod 2, libcamera 0.3)
# and tests/emulated-board/run.sh (the 6.12 kernel's kbuild and source).
# Idempotent; needs root (or sudo). Exit status 0; prints "added" when it added it.
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
if grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
  exit 0
fi
$SUDO tee /etc/apt/sources.list.d/bookworm-backports.sources >/dev/null <<'SOURCES'
Types: deb
URIs: http://deb.debian.org/debian
Suites: bookworm-backports
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SOURCES
$SUDO apt-get update -q >&2
echo added
