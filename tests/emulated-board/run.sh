#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The emulated board: cylscan's arm64 package on Debian arm64 in
# `qemu-system-aarch64 -M virt`, its GPIO lines on a gpio-sim chip and its
# camera on vivid, all real kernel drivers. See docs/emulated-board.md.
#   tests/emulated-board/run.sh
# Steps (each cached under build/emulated-cache, so a rerun is fast):
#   1. host packages: cross toolchain, qemu-system-arm, mmdebstrap, dwarves;
#   2. at the same time (they use different resources):
#      - the arm64 .deb and the feeder, built in EMULATED_BUILD_DIR (default:
#        scripts/cross-test.sh's build/cross-aarch64 when it exists, whose
#        objects are the same, else build/emulated-package);
#      - the guest root file system (mmdebstrap --variant=extract, arm64): the
#        .deb's run-time dependencies, busybox, libgpiod's and v4l-utils'
#        tools, the Debian backports 6.12 kernel and its headers;
#      - the kernel's source (two files of it) and the host's kbuild;
#   3. the .deb unpacked into the root file system, board/qemu-virt with it;
#   4. gpio-sim (with irq_sim compiled in: Debian builds neither) built out of
#      tree against the root file system's headers with the host's kbuild;
#   5. an initramfs (busybox) that loads virtio/9p, mounts the root file
#      system read-only over 9p and runs tests/emulated-board/guest.sh in it;
#   6. the in-process twin of the guest's scan (the same arm64 cylscan on the
#      virtual head, under qemu-user);
#   7. boots the guest (-nic none: no network) and reads the checks' results
#      from its console.
# Prints "N passed, N failed"; exits non-zero on any failure. qemu and the
# background steps are stopped on every exit path.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
here=$root/tests/emulated-board
cache=${EMULATED_CACHE:-$root/build/emulated-cache}
mkdir -p "$cache"
cd "$root"
t0=$SECONDS
step() { printf '\n== emulated-board: %s (%ds)\n' "$1" $((SECONDS - t0)); }
# shellcheck source=toolchain/target.sh
. "$root/toolchain/target.sh"

jobs_pids=()
qpid=""
# A background step and what it started (make, mmdebstrap, ...).
kill_tree() {
  local child
  for child in $(pgrep -P "$1" 2>/dev/null); do kill_tree "$child"; done
  kill "$1" 2>/dev/null || true
}
cleanup() {
  for p in "${jobs_pids[@]}" $qpid; do kill_tree "$p"; done
  for p in "${jobs_pids[@]}" $qpid; do wait "$p" 2>/dev/null || true; done
}
trap cleanup EXIT
trap 'cleanup; exit 130' INT TERM

step "host packages"
# The kernel's kbuild and source packages are backports' (or, for newer
# 6.12 ABIs, bookworm-security's).
scripts/enable-backports.sh
toolchain/install-cross.sh aarch64
"$root/toolchain/apt-install-missing.sh" qemu-system-arm dwarves xz-utils cpio kmod bc libelf-dev
sysroot=$root/build/sysroot-aarch64
toolchain/make-sysroot.sh aarch64 "$sysroot"

# --- three preparations at once; each logs to its own file -----------------
logs=$cache/logs
rm -rf "$logs"
mkdir -p "$logs"
# run_bg NAME COMMAND...: runs in the background, its output in logs/NAME.
run_bg() {
  local name=$1
  shift
  ("$@") >"$logs/$name" 2>&1 &
  jobs_pids+=($!)
  eval "pid_$name=\$!"
}
# wait_bg NAME: its exit status; its log's tail when it failed.
wait_bg() {
  local name=$1 pid
  eval "pid=\$pid_$name"
  if wait "$pid"; then
    echo "$name: done ($(tail -n 1 "$logs/$name"))"
    return 0
  fi
  echo "emulated-board: $name failed:" >&2
  tail -n 40 "$logs/$name" >&2
  return 1
}

# The arm64 package and the feeder. A build directory the cross stage made
# (tests on, the page off) is used with the virtual head turned back on (the
# cross stage builds without it): the feeder plays it, and the guest reads its
# scenes from the package's board/sim. Only the package's programs and the
# feeder are built, and the package is made without building the rest.
pkgdir=${EMULATED_BUILD_DIR:-}
if [ -z "$pkgdir" ]; then
  pkgdir=$root/build/emulated-package
  # scripts/cross-test.sh's build directory, when there is one.
  if [ -f "$root/build/cross-aarch64/CMakeCache.txt" ]; then pkgdir=$root/build/cross-aarch64; fi
fi
pkgdir=$(realpath -m "$pkgdir")
build_package() { "$root/toolchain/make-deb.sh" "$pkgdir" "$sysroot" cylscan_emulated_feeder; }

# The guest's root file system. Its packages: the .deb's Depends as the last
# build recorded them (or, the first time, the list below: what cylscan's
# arm64 package has depended on), what the guest script uses, the kernel.
# After the build the .deb's own Depends are checked against the list and
# the root file system is made again if one is missing.
rootfs=$cache/rootfs
depends_file=$cache/deb-depends
base_depends="libc6,libgcc-s1,libstdc++6,libopencv-core406,libopencv-imgproc406,\
libopencv-calib3d406,libpng16-16,libtiff6,libgpiod3/bookworm-backports,\
libcamera0.3/bookworm-backports,libmicrohttpd12,libturbojpeg0,libsystemd0,libtomlplusplus3,passwd"
rootfs_packages() { # rootfs_packages DEPENDS_LIST
  echo "$1,base-passwd,systemd,udev,curl,busybox-static,gpiod/bookworm-backports,v4l-utils,kmod,\
linux-image-$kver/bookworm-backports,linux-headers-$kver/bookworm-backports"
}
make_rootfs() { # make_rootfs PACKAGES
  local want=$1
  if [ -f "$cache/rootfs.stamp" ] && [ "$(cat "$cache/rootfs.stamp")" = "$want" ]; then
    echo "rootfs up to date"
    return 0
  fi
  rm -rf "$rootfs" "$cache/rootfs.stamp"
  mmdebstrap --mode=root --arch=arm64 --variant=extract --include="$want" bookworm "$rootfs" \
    "deb $mirror bookworm main" "deb $mirror bookworm-updates main" \
    "deb $mirror bookworm-backports main"
  # What the extract variant leaves to maintainer scripts (systemd-sysusers
  # adds the system users of the packages, cylscan's among them, at boot).
  "$root/toolchain/rootfs-fixups.sh" "$rootfs"
  # A provisioned board has its machine id (without one systemd would run
  # its interactive first-boot setup on the console).
  echo 4d3c0a5e2b1f4e6a9c8d7b6a5f4e3d2c >"$rootfs/etc/machine-id"
  echo "$want" >"$cache/rootfs.stamp"
  echo "rootfs made: $(du -sh "$rootfs" | cut -f1)"
}
depends_guess=$base_depends
if [ -s "$depends_file" ]; then depends_guess=$(cat "$depends_file"); fi

# The kernel's source (gpio-sim.c and irq_sim.c of it) and the host's kbuild
# tools of the kernel's version.
kdir=$cache/kernel-$kabi
fetch_kernel_source() {
  if [ -f "$kdir/linux-source-6.12/drivers/gpio/gpio-sim.c" ] && [ -d "$kdir/host" ]; then
    echo "kernel source cached"
    return 0
  fi
  mkdir -p "$kdir/debs"
  if ! ls "$kdir"/debs/linux-source-6.12_*.deb >/dev/null 2>&1 ||
    ! ls "$kdir"/debs/linux-kbuild-*.deb >/dev/null 2>&1; then
    local kpkgver
    kpkgver=$(apt-cache show "linux-kbuild-$kabi" | sed -n 's/^Version: //p' | head -n1)
    (cd "$kdir/debs" && apt-get download -q "linux-kbuild-$kabi" "linux-source-6.12=$kpkgver")
  fi
  rm -rf "$kdir/host" "$kdir/linux-source-6.12"
  dpkg-deb -x "$kdir"/debs/linux-kbuild-*.deb "$kdir/host"
  local srctar
  srctar=$(dpkg-deb -c "$kdir"/debs/linux-source-6.12_*.deb | awk '{print $6}' | grep 'linux-source-6.12.tar.xz$')
  dpkg-deb --fsys-tarfile "$kdir"/debs/linux-source-6.12_*.deb | tar -x -O "$srctar" |
    tar -xJ -C "$kdir" --wildcards '*/drivers/gpio/gpio-sim.c' '*/kernel/irq/irq_sim.c'
  echo "kernel source extracted"
}

step "package, root file system and kernel source, at once"
run_bg package build_package
run_bg rootfs make_rootfs "$(rootfs_packages "$depends_guess")"
run_bg ksource fetch_kernel_source
ok=1
wait_bg package || ok=0
wait_bg rootfs || ok=0
wait_bg ksource || ok=0
jobs_pids=()
[ "$ok" = 1 ] || exit 1
deb=$(ls -t "$pkgdir"/package/cylscan_*_arm64.deb | head -n1)
echo "package: $deb"
# The .deb's Depends (names, and the suite of the two from backports).
depends=$("$root/toolchain/deb-depends.sh" "$deb")
missing=$(comm -23 <(tr ',' '\n' <<<"$depends" | sort) <(tr ',' '\n' <<<"$depends_guess" | sort) | paste -sd, -)
echo "$depends" >"$depends_file"
if [ -n "$missing" ]; then
  step "root file system again: the .deb also depends on $missing"
  make_rootfs "$(rootfs_packages "$depends")"
fi

step "the package installed"
# As a user installs it: its files (the extract variant runs no maintainer
# scripts; systemd applies the package's sysusers.d and tmpfiles.d files at
# boot, as it does on a board), then the board chosen in the daemon's
# configuration. The unit is started by the checks once the devices exist.
dpkg-deb -x "$deb" "$rootfs"
sed -i 's|^board = .*|board = "/usr/share/cylscan/board/qemu-virt"|' "$rootfs/etc/cylscan/cylscan.toml"
grep -q '^board = "/usr/share/cylscan/board/qemu-virt"$' "$rootfs/etc/cylscan/cylscan.toml"
# The checks: a boot target and its service (tests/emulated-board/units).
cp "$here"/units/emulated-board.target "$here"/units/emulated-board.service "$rootfs/etc/systemd/system/"
rm -rf "$rootfs/opt/emulated-board"
mkdir -p "$rootfs/opt/emulated-board/modules"
cp "$here/guest.sh" "$here/guest-scan.sh" "$rootfs/opt/emulated-board/"
cp "$pkgdir/tests/emulated-board/cylscan_emulated_feeder" "$rootfs/opt/emulated-board/cylscan-emulated-feeder"
"$here/make-reference-board.sh" "$rootfs/usr/share/cylscan/board/qemu-virt/board.toml" "$here/head.toml" \
  "$rootfs/usr/share/cylscan/board/sim/scenes/sphere_on_plane.toml" "$rootfs/opt/emulated-board/reference-board"

step "gpio-sim"
if [ ! -f "$kdir/gpio-sim.ko" ]; then
  rm -rf "$kdir/mod" "$kdir/headers" "$kdir/headers-common"
  mkdir -p "$kdir/mod"
  cp "$kdir"/linux-source-6.12/drivers/gpio/gpio-sim.c "$kdir/mod/gpio-sim-main.c"
  # irq_sim compiled into the module: its one unexported call replaced.
  sed -e 's/handle_simple_irq(irq_to_desc(\([^)]*\)))/generic_handle_irq(\1)/' \
    "$kdir"/linux-source-6.12/kernel/irq/irq_sim.c >"$kdir/mod/irq_sim.c"
  printf 'obj-m := gpio-sim.o\ngpio-sim-y := gpio-sim-main.o irq_sim.o\n' >"$kdir/mod/Kbuild"
  # Copies of the headers (arm64 flavour and common) whose kbuild tools are
  # the host's: the packages point at their own (arm64) ones by path.
  khdr=$kdir/headers
  kcommon=$kdir/headers-common
  cp -a "$rootfs/usr/src/linux-headers-$kver" "$khdr"
  cp -a "$rootfs/usr/src/linux-headers-$kabi-common" "$kcommon"
  sed -i -e "s|/usr/src/linux-headers-$kabi-common|$kcommon|g" "$khdr/Makefile"
  kbuild=$kdir/host/usr/lib/linux-kbuild-$kabi
  for d in "$khdr" "$kcommon"; do
    rm -f "$d/scripts" "$d/tools"
    ln -s "$kbuild/scripts" "$d/scripts"
    ln -s "$kbuild/tools" "$d/tools"
  done
  make -s -C "$khdr" M="$kdir/mod" ARCH=arm64 CROSS_COMPILE=aarch64-linux-gnu- modules
  cp "$kdir/mod/gpio-sim.ko" "$kdir/gpio-sim.ko"
fi
cp "$kdir/gpio-sim.ko" "$rootfs/opt/emulated-board/modules/"

step "initramfs"
initrd=$cache/initrd-$kabi.cpio.gz
{ # made each time: a second
  ird=$(mktemp -d)
  mkdir -p "$ird"/{bin,dev,proc,sys,newroot,modules}
  cp "$rootfs/bin/busybox" "$ird/bin/busybox"
  # The modules that bring the 9p root (in dependency order; those built into
  # Debian's kernel are simply not found).
  : >"$ird/modules/order"
  for m in netfs 9pnet 9pnet_virtio 9p overlay; do
    f=$(find "$rootfs/lib/modules/$kver" -name "$m.ko.xz" | head -n1)
    if [ -n "$f" ]; then
      xz -dc "$f" >"$ird/modules/$m.ko"
      echo "$m" >>"$ird/modules/order"
    fi
  done
  cp "$here/initramfs-init" "$ird/init"
  chmod +x "$ird/init"
  (cd "$ird" && find . | cpio -o -H newc --quiet | gzip -1 >"$initrd")
  rm -rf "$ird"
}
vmlinuz=$rootfs/boot/vmlinuz-$kver

results=$cache/results
rm -rf "$results"
mkdir -p "$results"
step "the in-process twin"
# The same profile on the virtual head (tests/emulated-board/make-reference-board.sh),
# scanned by the same arm64 program under qemu-user (faster than in the
# emulated CPU); the guest compares its phase with its own.
frames=5
if qemu-aarch64 -L "$sysroot" "$pkgdir/tools/cylscan" scan --board "$rootfs/opt/emulated-board/reference-board" \
  --frames "$frames" --out "$results/ref" >"$results/ref.out" 2>&1 &&
  qemu-aarch64 -L "$sysroot" "$pkgdir/tools/cylscan" phase --out "$results/ref-phase" "$results/ref" \
    >>"$results/ref.out" 2>&1; then
  grep '^scan' "$results/ref.out" || true
else
  echo "the in-process reference scan failed:"
  cat "$results/ref.out"
fi

step "boot"
console=$cache/console.log
timeout_s=${EMULATED_TIMEOUT_S:-600}
qemu-system-aarch64 -M virt -cpu cortex-a57 -smp 2 -m 1024 -accel tcg,thread=multi -nic none \
  -nographic -no-reboot -kernel "$vmlinuz" -initrd "$initrd" \
  -append "console=ttyAMA0 panic=-1 quiet loglevel=3 systemd.unit=emulated-board.target systemd.show_status=0 systemd.firstboot=off" \
  -virtfs "local,path=$rootfs,mount_tag=rootfs,security_model=none,readonly=on" \
  -virtfs "local,path=$results,mount_tag=results,security_model=none" \
  </dev/null >"$console" 2>&1 &
qpid=$!
# The guest powers off when its script ends; a hung guest is killed.
end=$((SECONDS + timeout_s))
while kill -0 "$qpid" 2>/dev/null; do
  if [ "$SECONDS" -ge "$end" ]; then
    echo "emulated-board: the guest did not finish within ${timeout_s}s" >&2
    echo "FAIL guest finished within ${timeout_s}s" >>"$console"
    break
  fi
  sleep 1
done
cleanup
qpid=""

step "results"
grep -a -E '^(PASS|FAIL|INFO) ' "$console" | tr -d '\r' || true
passed=$(grep -a -c '^PASS ' "$console" || true)
failed=$(grep -a -c '^FAIL ' "$console" || true)
if ! grep -a -q '^GUEST DONE' "$console"; then
  failed=$((failed + 1))
  echo "FAIL the guest script ran to its end (console: $console)"
  tail -n 30 "$console"
fi
echo "emulated-board: total $((SECONDS - t0))s"
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
