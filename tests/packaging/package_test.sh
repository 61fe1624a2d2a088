#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The amd64 Debian package, end to end (CTest: packaging.deb, label packaging):
#   tests/packaging/package_test.sh BUILD_DIR
# 1. builds it (cpack -G DEB in BUILD_DIR, which builds what is missing first);
# 2. inspects it: its name, control fields, conffiles and maintainer scripts;
#    Depends, and the DEP-5 copyright file, name the package of every shared
#    library the binaries link;
#    the files are where the unit, the config and the udev/tmpfiles rules say;
# 3. installs it with apt into a throwaway Debian root made by mmdebstrap
#    (minbase), where its postinst runs: the files land, the cylscan user
#    exists in gpio and video, the data directory is its own, the unit is
#    enabled and passes systemd-analyze verify;
# 4. removes it (data and config kept) and purges it (both gone).
# Prints "N passed, N failed"; exit 77 (skipped) without root or user namespaces.
set -uo pipefail

build=${1:?usage: package_test.sh BUILD_DIR}
build=$(cd "$build" && pwd)
src=$(cd "$(dirname "$0")/../.." && pwd)
work=$build/package-test
cache=$build/package-test-cache   # apt's downloads for the throwaway root, kept between runs
passed=0
failed=0
check() { # check DESCRIPTION COMMAND...
  local what=$1
  shift
  if "$@" >"$work/check.out" 2>&1; then
    passed=$((passed + 1))
    echo "ok   $what"
  else
    failed=$((failed + 1))
    echo "FAIL $what"
    sed 's/^/     | /' "$work/check.out" | tail -n 15
  fi
}
finish() {
  echo "package test: $passed passed, $failed failed"
  [ "$failed" -eq 0 ]
  exit $?
}
t0=$SECONDS
phase() { echo "-- $1 ($((SECONDS - t0)) s)"; }

if [ "$(id -u)" -ne 0 ] && ! unshare --user --map-root-user true 2>/dev/null; then
  echo "package test: skipped (needs root or user namespaces for mmdebstrap)"
  exit 77
fi
mode=root
if [ "$(id -u)" -ne 0 ]; then mode=unshare; fi

# What it needs on a fresh machine (also in scripts/install-deps.sh).
need=()
for p in mmdebstrap dpkg-dev systemd binutils device-tree-compiler; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [ "${#need[@]}" -gt 0 ]; then
  if [ "$(id -u)" -ne 0 ]; then
    echo "package test: missing ${need[*]} (run scripts/install-deps.sh)"
    exit 1
  fi
  apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${need[@]}" ||
    exit 1
fi

rm -rf "$work"
mkdir -p "$work" "$cache"

phase "cpack"
version=$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$build/CMakeCache.txt")
if ! (cd "$build" && cpack -G DEB -B "$work/out" >"$work/cpack.log" 2>&1); then
  tail -30 "$work/cpack.log"
  check "cpack -G DEB builds the package" false
  finish
fi
deb=$work/out/cylscan_${version}_amd64.deb
check "the package is cylscan_${version}_amd64.deb" test -f "$deb"
[ -f "$deb" ] || finish

phase "inspect"
dpkg-deb -c "$deb" | awk '{ print $6 }' | sed 's|^\./|/|; s|/$||' >"$work/files"
field() { dpkg-deb -f "$deb" "$1"; }
has() { grep -qx "$1" "$work/files"; }
check "Package: cylscan" test "$(field Package)" = cylscan
check "Architecture: amd64" test "$(field Architecture)" = amd64
check "Version: $version" test "$(field Version)" = "$version"
mkdir -p "$work/control"
dpkg-deb -e "$deb" "$work/control"
for s in postinst prerm postrm; do
  check "maintainer script $s is executable" test -x "$work/control/$s"
done
check "/etc/cylscan/cylscan.toml is a conffile" grep -qx /etc/cylscan/cylscan.toml "$work/control/conffiles"

# The unit's files: ExecStart's binary and the config it names; the config's
# board, page and data directory; the data directory writable by the unit and
# made by tmpfiles; the udev rules and sysusers.
mkdir -p "$work/tree"
dpkg-deb -x "$deb" "$work/tree"
unit=/lib/systemd/system/cylscand.service
check "the unit $unit" has "$unit"
exec_start=$(sed -n 's/^ExecStart=//p' "$work/tree$unit")
exec_bin=${exec_start%% *}
check "ExecStart's program $exec_bin" has "$exec_bin"
check "ExecStart's program is executable" test -x "$work/tree$exec_bin"
check "the CLI /usr/bin/cylscan" has /usr/bin/cylscan
copyright=/usr/share/doc/cylscan/copyright
check "the licences $copyright" has "$copyright"
check "$copyright is machine-readable (DEP-5)" \
  grep -qx 'Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/' "$work/tree$copyright"
check "$copyright: cylscan is under Apache-2.0" grep -qx 'License: Apache-2.0' "$work/tree$copyright"
config=$(sed -n 's/.*--config \([^ ]*\).*/\1/p' <<<"$exec_start")
check "ExecStart's --config $config" has "$config"
toml() { sed -n "s/^$1 *= *\"\\(.*\\)\"/\\1/p" "$work/tree$config"; }
board=$(toml board)
web=$(toml web_root)
data=$(toml data_dir)
check "the config's board $board/board.toml" has "$board/board.toml"
check "the config's board's head model" has "$board/head.toml"
check "the config's web_root $web/index.html" has "$web/index.html"
for b in rpi5 rpi4 generic-arm64 qemu-virt; do
  check "board profile $b" has "/usr/share/cylscan/board/$b/board.toml"
done
check "ReadWritePaths is the config's data_dir $data" grep -qx "ReadWritePaths=$data" "$work/tree$unit"
check "tmpfiles makes $data" grep -q "^d $data " "$work/tree/usr/lib/tmpfiles.d/cylscan.conf"
check "udev rules for the gpio and video groups" grep -q 'GROUP="gpio"' "$work/tree/lib/udev/rules.d/60-cylscan.rules"
check "sysusers puts cylscan in gpio and video" grep -q "^m cylscan video" "$work/tree/usr/lib/sysusers.d/cylscan.conf"
check "the Pi overlays compile (dtc)" bash -c "dtc -@ -q -I dts -O dtb -o /dev/null '$src/board/rpi4/cylscan-pins-overlay.dts' &&
                                             dtc -@ -q -I dts -O dtb -o /dev/null '$src/board/rpi5/cylscan-pins-overlay.dts'"

# Depends: the package of every library a binary links (as dpkg -S finds it on
# this host, where the build linked them), plus passwd for the user.
depends=$(field Depends)
depends_on() { tr ',' '\n' <<<"$depends" | awk '{ print $1 }' | grep -qxF "$1"; }
echo "   Depends: $depends"
for bin in /usr/bin/cylscan "$exec_bin"; do
  [ -f "$work/tree$bin" ] || continue
  for soname in $(readelf -d "$work/tree$bin" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'); do
    path=$(ldconfig -p | awk -v s="$soname" '$1 == s && /x86-64/ { print $NF; exit }')
    pkg=$(dpkg -S "$(readlink -f "$path")" 2>/dev/null | head -n1 | cut -d: -f1)
    [ -n "$pkg" ] || pkg=$(dpkg -S "$path" 2>/dev/null | head -n1 | cut -d: -f1)
    check "Depends names $pkg (for $soname of $bin)" depends_on "$pkg"
    check "$copyright names $pkg (for $soname of $bin)" grep -qwF -- "$pkg" "$work/tree$copyright"
  done
done
check "Depends names passwd (postinst's useradd)" depends_on passwd

phase "throwaway root (mmdebstrap)"
mirror=$(apt-get indextargets --format '$(RELEASE) $(SITE)' 'Identifier: Packages' 2>/dev/null |
  awk '$1 == "bookworm" { print $2; exit }')
root=$work/root
# minbase with systemd (whose unit tree systemd-analyze verifies against),
# then the package installed by apt inside it, as a user would
# (its Depends from the mirror, bookworm-backports for libgpiod 3 and
# libcamera 0.3); apt's downloads are kept in $cache for the next run.
if ! mmdebstrap --mode="$mode" --variant=minbase --include=systemd \
  --aptopt='APT::Keep-Downloaded-Packages "true"' \
  --setup-hook="mkdir -p \"\$1/var/cache/apt/archives\"" \
  --setup-hook="sync-in '$cache' /var/cache/apt/archives" \
  --customize-hook="copy-in '$deb' /tmp" \
  --customize-hook="chroot \"\$1\" apt-get install -y -q --no-install-recommends /tmp/$(basename "$deb")" \
  --customize-hook="sync-out /var/cache/apt/archives '$cache'" \
  bookworm "$root" "deb $mirror bookworm main" "deb $mirror bookworm-updates main" \
  "deb $mirror bookworm-backports main" >"$work/mmdebstrap.log" 2>&1; then
  tail -30 "$work/mmdebstrap.log"
  check "mmdebstrap makes a minimal root and apt installs the package into it" false
  finish
fi
rm -f "$cache"/cylscan_*.deb
check "dpkg says cylscan is installed" bash -c "chroot '$root' dpkg-query -W -f='\${Status}' cylscan | grep -q 'install ok installed'"
for f in "$exec_bin" /usr/bin/cylscan "$config" "$board/board.toml" "$web/index.html" "$unit" \
  /lib/udev/rules.d/60-cylscan.rules /usr/lib/tmpfiles.d/cylscan.conf; do
  check "installed: $f" test -e "$root$f"
done
check "postinst: user cylscan" chroot "$root" getent passwd cylscan
check "postinst: cylscan in gpio and video" bash -c "chroot '$root' id -nG cylscan | tr ' ' '\n' | grep -qx gpio &&
                                                     chroot '$root' id -nG cylscan | tr ' ' '\n' | grep -qx video"
check "postinst: $data owned by cylscan, mode 750" test "$(chroot "$root" stat -c '%U:%G %a' "$data")" = "cylscan:cylscan 750"
check "postinst: the unit is enabled" test -L "$root/etc/systemd/system/multi-user.target.wants/cylscand.service"
check "the programs find their libraries in the root" bash -c "chroot '$root' ldd $exec_bin /usr/bin/cylscan | grep -q 'not found' && exit 1 || exit 0"
check "cylscan --version runs in the root" chroot "$root" /usr/bin/cylscan --version
check "$exec_bin --version runs in the root" chroot "$root" "$exec_bin" --version
check "systemd-analyze verify of the installed unit" systemd-analyze verify --root="$root" cylscand.service

phase "remove and purge"
echo scan >"$root$data/kept"
chroot "$root" dpkg --remove cylscan >"$work/remove.log" 2>&1
check "remove: the programs are gone" test ! -e "$root/usr/bin/cylscan"
check "remove: the data and the config stay" test -e "$root$data/kept" -a -e "$root$config"
chroot "$root" dpkg --purge cylscan >>"$work/remove.log" 2>&1
check "purge: the data directory is gone" test ! -e "$root$data"
check "purge: the config is gone" test ! -e "$root$config"
check "purge: the enablement is gone" test ! -e "$root/etc/systemd/system/multi-user.target.wants/cylscand.service"

phase "done"
[ "$failed" -eq 0 ] && rm -rf "$root"   # kept for a look when something failed
finish
