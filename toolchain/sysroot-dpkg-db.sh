#!/usr/bin/env bash
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
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for deb in "$@"; do
  pkg=$(dpkg-deb -f "$deb" Package)
  arch=$(dpkg-deb -f "$deb" Architecture)
  name=$pkg
  if [ "$(dpkg-deb -f "$deb" Multi-Arch)" = same ]; then name=$pkg:$arch; fi
  {
    echo "Package: $pkg"
    echo "Status: install ok installed"
    dpkg-deb -f "$deb" | grep -v '^Package:'
    echo
  } >>"$db/status"
  dpkg-deb --fsys-tarfile "$deb" | tar -t | sed -e 's|^\./|/|' -e 's|/$||' -e '/^$/d' \
    -e "s|^|$sysroot|" >"$db/info/$name.list"
  rm -rf "${tmp:?}"/*
  dpkg-deb -e "$deb" "$tmp"
  for f in shlibs symbols; do
    if [ -f "$tmp/$f" ]; then cp "$tmp/$f" "$db/info/$name.$f"; fi
  done
done
# The database's architectures: dpkg-query treats the target's as foreign.
{
  dpkg --print-architecture
  for deb in "$@"; do dpkg-deb -f "$deb" Architecture; done | sort -u | grep -vx all
} | awk '!seen[$0]++' >"$db/arch"
echo "sysroot-dpkg-db: $# packages registered in $db"
