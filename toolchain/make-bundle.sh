#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# A signed RAUC update bundle (verity format) holding one root file system
# for a board's slots: OUT.raucb, which a head whose keyring trusts the
# signer and whose compatible string is cylscan-BOARD installs into its
# slot not running (docs/image.md).
#   CYLSCAN_UPDATE_CERT=... CYLSCAN_UPDATE_KEY=... [CYLSCAN_UPDATE_KEYRING=...] \
#     toolchain/make-bundle.sh ROOT_EXT4 BOARD VERSION OUT.raucb
# The key may be a PKCS#11 URI, so that it never lies in a file here. With
# CYLSCAN_UPDATE_KEYRING, the signature is checked against it once made.
set -euo pipefail
[ $# -eq 4 ] || { echo "usage: toolchain/make-bundle.sh ROOT_EXT4 BOARD VERSION OUT.raucb" >&2; exit 2; }
rootfs=$1 board=$2 version=$3 out=$4
[ -f "$rootfs" ] || { echo "make-bundle: $rootfs: no such root file system" >&2; exit 2; }
: "${CYLSCAN_UPDATE_CERT:?make-bundle: CYLSCAN_UPDATE_CERT names the signing certificate}"
: "${CYLSCAN_UPDATE_KEY:?make-bundle: CYLSCAN_UPDATE_KEY names the signing key}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/make-bundle.XXXXXX")
trap 'rm -rf "$dir"' EXIT
mkdir "$dir/content"
cat >"$dir/content/manifest.raucm" <<MANIFEST
[update]
compatible=cylscan-$board
version=$version
description=cylscan $version for $board

[bundle]
format=verity

[image.rootfs]
filename=root.ext4
MANIFEST
# A hard link when the file system allows: the root is hundreds of MiB.
ln "$rootfs" "$dir/content/root.ext4" 2>/dev/null || cp "$rootfs" "$dir/content/root.ext4"
rm -f "$out"
# zstd at level 3: on the qemu-virt root, 2 s and 247 MiB against 40 s and
# 223 MiB at mksquashfs's default level 15; the head unpacks either faster
# than it writes the slot.
rauc bundle --cert="$CYLSCAN_UPDATE_CERT" --key="$CYLSCAN_UPDATE_KEY" \
  --mksquashfs-args="-comp zstd -Xcompression-level 3" "$dir/content" "$out" >"$dir/log" 2>&1 ||
  { cat "$dir/log" >&2; exit 1; }
if [ -n "${CYLSCAN_UPDATE_KEYRING:-}" ]; then
  rauc info --keyring="$CYLSCAN_UPDATE_KEYRING" "$out" >"$dir/log" 2>&1 || { cat "$dir/log" >&2; exit 1; }
fi
echo "$out"
