#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Registers the packages unpacked into a sysroot in a dpkg database of its own
# (SYSROOT/.cylscan-dpkg), so that the host's dpkg-shlibdeps can say which
# target packages a cross-built binary needs, from their shlibs and symbols
# files, as it does for native builds:
#   toolchain/sysroot-dpkg-db.sh SYSROOT DEB...
# (make-sysroot.sh runs it from mmdebstrap's extract hook, while the .debs
# are still in the sysroot's apt cache). `mmdebstrap --variant=extract` runs
# no dpkg, so the sysroot has no database. The file lists hold the files'
# paths under SYSROOT (dpkg-shlibdeps finds the target's libraries there), so
# this database is for dpkg-shlibdeps only: packaging/packaging.cmake points
# DPKG_ADMINDIR at it for a cross package.
set -euo pipefail
sysroot=$(cd "${1:?usage: sysroot-dpkg-db.sh SYSROOT DEB...}" && pwd)
shift
db=$sysroot/.cylscan-dpkg
rm -rf "$db"
mkdir -p "$db/info" "$db/updates" "$db/triggers"
: >"$db/status"
echo 1 >"$db/info/format" # multiarch file names (pkg:arch.list for Multi-Arch: same)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# One package: its status stanza and file list to $tmp/<n>.*, shlibs and symbols to info/.
register() {
  local deb=$1 n=$2 ctl=$tmp/ctl.$2 pkg arch name
  mkdir -p "$ctl"
  dpkg-deb -e "$deb" "$ctl"
  pkg=$(sed -n 's/^Package: //p' "$ctl/control")
  arch=$(sed -n 's/^Architecture: //p' "$ctl/control")
  name=$pkg
  if grep -qx 'Multi-Arch: same' "$ctl/control"; then name=$pkg:$arch; fi
  {
    echo "Package: $pkg"
    echo "Status: install ok installed"
    grep -v '^Package:' "$ctl/control"
    echo
  } >"$tmp/$n.status"
  echo "$arch" >"$tmp/$n.arch"
  dpkg-deb --fsys-tarfile "$deb" | tar -t | sed -e 's|^\./|/|' -e 's|/$||' -e '/^$/d' \
    -e "s|^|$sysroot|" >"$db/info/$name.list"
  for f in shlibs symbols; do
    if [ -f "$ctl/$f" ]; then cp "$ctl/$f" "$db/info/$name.$f"; fi
  done
  rm -rf "$ctl"
}
export -f register
export tmp db sysroot
# Two at a time: the time goes into decompressing each package's data.
i=0
for deb in "$@"; do
  i=$((i + 1))
  printf '%s\0%s\0' "$deb" "$i"
done | xargs -0 -n2 -P"$(nproc)" bash -c 'register "$1" "$2"' _ # (the quoted $1 $2 are bash -c's)
for ((i = 1; i <= $#; i++)); do cat "$tmp/$i.status"; done >"$db/status"

# The database's architectures: dpkg-query treats the target's as foreign.
{
  dpkg --print-architecture
  cat "$tmp"/*.arch | sort -u | grep -vx all
} | awk '!seen[$0]++' >"$db/arch"
echo "sysroot-dpkg-db: $# packages registered in $db"
