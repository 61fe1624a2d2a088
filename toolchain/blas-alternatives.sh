#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The BLAS and LAPACK links that Debian's update-alternatives makes in a
# maintainer script, for a root that `mmdebstrap --variant=extract` made
# without running any: OpenCV links libblas.so.3 and liblapack.so.3, and
# OpenBLAS's own libopenblas.so.0 is an alternative too. The implementation
# chosen is the one the alternatives' priorities would choose: OpenBLAS
# (single-threaded first) before the reference BLAS. A link that exists is
# kept. Used by toolchain/make-sysroot.sh and toolchain/rootfs-fixups.sh.
#   toolchain/blas-alternatives.sh LIBDIR    (e.g. ROOT/usr/lib/aarch64-linux-gnu)
# Exits 1 when LIBDIR has no implementation of libblas.so.3 or liblapack.so.3.
set -euo pipefail
libdir=${1:?usage: blas-alternatives.sh LIBDIR}
for so in libblas.so.3 liblapack.so.3 libopenblas.so.0; do
  [ -e "$libdir/$so" ] && continue
  impl=""
  for candidate in openblas-serial openblas-pthread blas lapack atlas; do
    if [ -e "$libdir/$candidate/$so" ]; then
      impl=$candidate/$so
      break
    fi
  done
  if [ -n "$impl" ]; then
    ln -sf "$impl" "$libdir/$so"
  elif [ "$so" != libopenblas.so.0 ]; then
    echo "blas-alternatives: no $so implementation under $libdir" >&2
    exit 1
  fi
done
