#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# What `mmdebstrap --variant=extract` leaves undone in an arm64 root file
# system, because it runs no maintainer scripts; used by the emulated board's
# root and by toolchain/make-image.sh:
#   - the mount points systemd expects;
#   - the base accounts of base-passwd (systemd-sysusers adds the rest);
#   - the BLAS/LAPACK alternatives that OpenCV links (as make-sysroot.sh);
#   - modules.dep for every kernel in the root (the guest's modprobe).
#   toolchain/rootfs-fixups.sh ROOT
set -euo pipefail
root=$1
mkdir -p "$root"/{proc,sys,dev,run,tmp,var/tmp}
for f in passwd group; do
  [ -s "$root/etc/$f" ] || cp "$root/usr/share/base-passwd/$f.master" "$root/etc/$f"
done
libdir=$root/usr/lib/aarch64-linux-gnu
for lib in blas lapack; do
  if [ ! -e "$libdir/lib$lib.so.3" ]; then
    impl=$(ls "$libdir"/{blas,lapack,openblas-pthread,atlas}/lib$lib.so.3 2>/dev/null | head -n1 || true)
    if [ -n "$impl" ]; then ln -sf "${impl#"$libdir"/}" "$libdir/lib$lib.so.3"; fi
  fi
done
for kdir in "$root"/lib/modules/*; do
  [ -d "$kdir" ] || continue
  depmod -b "$root" "$(basename "$kdir")"
done
