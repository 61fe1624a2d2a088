#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs those of the named Debian packages that are not installed yet
# (apt's lists updated first, only when something is missing). Needs root
# (or sudo) then; does nothing when all are there.
#   toolchain/apt-install-missing.sh PACKAGE...
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive
need=()
for p in "$@"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
[ "${#need[@]}" -gt 0 ] || exit 0
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${need[@]}"
