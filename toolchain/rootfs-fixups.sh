#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# What `mmdebstrap --variant=extract` leaves undone in an arm64 root file
# system, because it runs no maintainer scripts; used by the emulated board's
# root and by toolchain/make-image.sh:
#   - the mount points systemd expects;
#   - the base accounts of base-passwd (systemd-sysusers adds the rest);
#   - the BLAS/LAPACK alternatives that OpenCV links (blas-alternatives.sh);
#   - modules.dep for every kernel in the root (the guest's modprobe).
#   toolchain/rootfs-fixups.sh ROOT
set -euo pipefail
root=$1
mkdir -p "$root"/{proc,sys,dev,run,tmp,var/tmp}
for f in passwd group; do
  [ -s "$root/etc/$f" ] || cp "$root/usr/share/base-passwd/$f.master" "$root/etc/$f"
done
"$(dirname "$0")/blas-alternatives.sh" "$root/usr/lib/aarch64-linux-gnu"
for kdir in "$root"/lib/modules/*; do
  [ -d "$kdir" ] || continue
  depmod -b "$root" "$(basename "$kdir")"
done
