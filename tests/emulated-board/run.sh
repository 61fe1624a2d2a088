#!/usr/bin/env bash
# The emulated board (issue #8): cylscan's arm64 package on Debian arm64 in
# `qemu-system-aarch64 -M virt`, its GPIO lines on a gpio-sim chip and its
# camera on vivid, all real kernel drivers. See docs/emulated-board.md.
#   tests/emulated-board/run.sh
# Steps (each cached under build/emulated-cache, so a rerun is fast):
#   1. host packages: cross toolchain, qemu-system-arm, mmdebstrap, dwarves;
#   2. the arm64 .deb (scripts/cross-test.sh's package step, build/emulated-package);
#   3. the guest root file system (mmdebstrap --variant=extract, arm64): the
#      .deb's run-time dependencies, the Debian backports 6.12 kernel and its
#      headers, libgpiod's and v4l-utils' tools; the .deb unpacked into it;
#   4. gpio-sim (with irq_sim compiled in: Debian builds neither) built out of
#      tree against those headers with the host's linux-kbuild;
#   5. an initramfs (busybox) that loads virtio/9p, mounts the root file
#      system read-only over 9p and runs tests/emulated-board/guest.sh in it;
#   6. boots the guest (-nic none: no network) and reads the checks' results
#      from its console.
# Prints "N passed, N failed"; exits non-zero on any failure. qemu is killed
# on every exit path.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
here=$root/tests/emulated-board
cache=${EMULATED_CACHE:-$root/build/emulated-cache}
mkdir -p "$cache"
cd "$root"
export DEBIAN_FRONTEND=noninteractive
t0=$SECONDS
step() { printf '\n== emulated-board: %s (%ds)\n' "$1" $((SECONDS - t0)); }
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi

# The kernel: Debian bookworm-backports' 6.12 for arm64.
kabi=${EMULATED_KERNEL_ABI:-6.12.95+deb12}
kver=$kabi-arm64

step "host packages"
toolchain/install-cross.sh aarch64
need=()
for p in qemu-system-arm dwarves xz-utils cpio kmod bc libelf-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [ "${#need[@]}" -gt 0 ]; then
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${need[@]}"
fi

step "arm64 package"
sysroot=$root/build/sysroot-aarch64
toolchain/make-sysroot.sh aarch64 "$sysroot"
pkgdir=$root/build/emulated-package
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
# Tests on for the feeder (tests/emulated-board/feeder), which is built but
# not packaged; only the programs the package installs and the feeder are built.
cmake --preset aarch64 -B "$pkgdir" "${launcher[@]}" -DCYLSCAN_SYSROOT="$sysroot" \
  -DCYLSCAN_BUILD_TESTS=ON -DCYLSCAN_BUILD_WEB=OFF >/dev/null
cmake --build "$pkgdir" -j"$(nproc)" --target cylscan cylscand cylscan_emulated_feeder
(cd "$pkgdir" && cpack -G DEB -B "$pkgdir/package" >/dev/null)
deb=$(ls -t "$pkgdir"/package/cylscan_*_arm64.deb | head -n1)
echo "package: $deb"

step "guest root file system"
mirror=${CYLSCAN_DEBIAN_MIRROR:-http://deb.debian.org/debian}
rootfs=$cache/rootfs
# The .deb's Depends (names only), what the guest script uses, the kernel.
deps=$(dpkg-deb -f "$deb" Depends | tr ',' '\n' | sed -e 's/(.*)//' -e 's/ //g' | grep -v '^$' |
  sed -e 's|^libgpiod3$|libgpiod3/bookworm-backports|' -e 's|^libcamera0.3$|libcamera0.3/bookworm-backports|')
pkgs="$(echo "$deps" | tr '\n' ',')busybox-static,gpiod/bookworm-backports,v4l-utils,kmod"
pkgs="$pkgs,linux-image-$kver/bookworm-backports,linux-headers-$kver/bookworm-backports"
want="$pkgs"
if [ ! -f "$cache/rootfs.stamp" ] || [ "$(cat "$cache/rootfs.stamp")" != "$want" ]; then
  rm -rf "$rootfs"
  mmdebstrap --mode=root --arch=arm64 --variant=extract --include="$pkgs" bookworm "$rootfs" \
    "deb $mirror bookworm main" "deb $mirror bookworm-updates main" \
    "deb $mirror bookworm-backports main"
  echo "$want" >"$cache/rootfs.stamp"
fi
# The package as a user installs it (its files; the extract variant runs no
# maintainer scripts, so the user and groups they make are made below).
dpkg-deb -x "$deb" "$rootfs"
mkdir -p "$rootfs/etc"
grep -q '^cylscan:' "$rootfs/etc/passwd" 2>/dev/null ||
  echo 'cylscan:x:999:999:cylscan:/var/lib/cylscan:/usr/sbin/nologin' >>"$rootfs/etc/passwd"
# What the extract variant leaves to maintainer scripts: mount points, and
# the BLAS/LAPACK alternatives OpenCV links (as toolchain/make-sysroot.sh).
mkdir -p "$rootfs"/{proc,sys,dev,run,tmp,var/tmp,var/lib/cylscan}
libdir=$rootfs/usr/lib/aarch64-linux-gnu
for lib in blas lapack; do
  if [ ! -e "$libdir/lib$lib.so.3" ]; then
    impl=$(ls "$libdir"/{blas,lapack,openblas-pthread,atlas}/lib$lib.so.3 2>/dev/null | head -n1 || true)
    [ -n "$impl" ] && ln -sf "${impl#"$libdir"/}" "$libdir/lib$lib.so.3"
  fi
done
mkdir -p "$rootfs/opt/emulated-board"
cp "$here/guest.sh" "$here/guest-scan.sh" "$pkgdir/tests/emulated-board/cylscan_emulated_feeder" \
  "$rootfs/opt/emulated-board/"
mv "$rootfs/opt/emulated-board/cylscan_emulated_feeder" "$rootfs/opt/emulated-board/cylscan-emulated-feeder"
rm -rf "$rootfs/opt/emulated-board/reference-board"
"$here/make-reference-board.sh" "$rootfs/usr/share/cylscan/board/qemu-virt/board.toml" "$here/head.toml" \
  "$rootfs/usr/share/cylscan/board/sim/scenes/sphere_on_plane.toml" "$rootfs/opt/emulated-board/reference-board"

step "kernel modules"
kdir=$cache/kernel-$kabi
if [ ! -f "$kdir/gpio-sim.ko" ]; then
  # The host's kbuild tools and the kernel's source, of the kernel's version.
  if ! ls "$kdir"/debs/linux-source-6.12_*.deb >/dev/null 2>&1; then
    rm -rf "$kdir"
    mkdir -p "$kdir/debs"
    kpkgver=$(apt-cache show "linux-kbuild-$kabi" | sed -n 's/^Version: //p' | head -n1)
    (cd "$kdir/debs" && apt-get download -q "linux-kbuild-$kabi" "linux-source-6.12=$kpkgver")
  fi
  rm -rf "$kdir/host" "$kdir/mod" "$kdir/headers" "$kdir/headers-common" "$kdir/linux-source-6.12"
  dpkg-deb -x "$kdir"/debs/linux-kbuild-*.deb "$kdir/host"
  srctar=$(dpkg-deb -c "$kdir"/debs/linux-source-6.12_*.deb | awk '{print $6}' | grep 'linux-source-6.12.tar.xz$')
  dpkg-deb --fsys-tarfile "$kdir"/debs/linux-source-6.12_*.deb | tar -x -O "$srctar" |
    tar -xJ -C "$kdir" --wildcards '*/drivers/gpio/gpio-sim.c' '*/kernel/irq/irq_sim.c'
  mkdir -p "$kdir/mod"
  cp "$kdir"/linux-source-6.12/drivers/gpio/gpio-sim.c "$kdir/mod/"
  # irq_sim compiled into the module: its one unexported call replaced.
  sed -e 's/handle_simple_irq(irq_to_desc(\([^)]*\)))/generic_handle_irq(\1)/' \
    "$kdir"/linux-source-6.12/kernel/irq/irq_sim.c >"$kdir/mod/irq_sim.c"
  printf 'obj-m := gpio-sim.o\ngpio-sim-y := gpio-sim-main.o irq_sim.o\n' >"$kdir/mod/Kbuild"
  mv "$kdir/mod/gpio-sim.c" "$kdir/mod/gpio-sim-main.c"
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
  make -C "$khdr" M="$kdir/mod" ARCH=arm64 CROSS_COMPILE=aarch64-linux-gnu- modules
  cp "$kdir/mod/gpio-sim.ko" "$kdir/gpio-sim.ko"
fi
# v4l2loopback (Debian's DKMS source, backports): the scan's camera. Each
# frame the feeder writes is one captured frame, numbered in order and
# stamped when written, as an externally triggered sensor delivers them.
# (vivid's loopback is checked too, but its capture runs on its own clock:
# frames come whether or not one was written, see docs/emulated-board.md.)
if [ ! -f "$kdir/v4l2loopback.ko" ]; then
  lb=$cache/v4l2loopback
  rm -rf "$lb"
  mkdir -p "$lb"
  (cd "$lb" && apt-get download -q v4l2loopback-dkms/bookworm-backports)
  dpkg-deb -x "$lb"/v4l2loopback-dkms_*.deb "$lb/x"
  src=$(ls -d "$lb"/x/usr/src/v4l2loopback-*)
  make -C "$kdir/headers" M="$src" ARCH=arm64 CROSS_COMPILE=aarch64-linux-gnu- modules
  cp "$src/v4l2loopback.ko" "$kdir/v4l2loopback.ko"
fi

step "initramfs"
# modules.dep for the guest's modprobe (the extract variant ran no depmod).
[ -f "$rootfs/lib/modules/$kver/modules.dep" ] || depmod -b "$rootfs" "$kver"
mkdir -p "$rootfs/opt/emulated-board/modules"
cp "$kdir/gpio-sim.ko" "$kdir/v4l2loopback.ko" "$rootfs/opt/emulated-board/modules/"
initrd=$cache/initrd-$kabi.cpio.gz
if [ ! -f "$initrd" ]; then
  ird=$(mktemp -d)
  mkdir -p "$ird"/{bin,dev,proc,sys,newroot,modules}
  cp "$rootfs/bin/busybox" "$ird/bin/busybox"
  # The modules that bring the 9p root (in dependency order; those built into
  # Debian's kernel are simply not found).
  : >"$ird/modules/order"
  for m in netfs 9pnet 9pnet_virtio 9p; do
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
fi
vmlinuz=$rootfs/boot/vmlinuz-$kver

step "boot"
console=$cache/console.log
qpid=""
cleanup() { if [ -n "$qpid" ]; then kill "$qpid" 2>/dev/null || true; wait "$qpid" 2>/dev/null || true; fi; }
trap cleanup EXIT
trap 'cleanup; exit 130' INT TERM
results=$cache/results
rm -rf "$results"
mkdir -p "$results"
timeout_s=${EMULATED_TIMEOUT_S:-900}
# The in-process twin of the guest's scan (tests/emulated-board/make-reference-board.sh):
# the same arm64 program on the virtual head, under qemu-user with the sysroot
# (faster than in the emulated CPU); the guest compares its phase with its own.
frames=5
qemu-aarch64 -L "$sysroot" "$pkgdir/tools/cylscan" scan --board "$rootfs/opt/emulated-board/reference-board" \
  --frames "$frames" --out "$results/ref" >"$results/ref.out" 2>&1 &&
  qemu-aarch64 -L "$sysroot" "$pkgdir/tools/cylscan" phase --out "$results/ref-phase" "$results/ref" \
    >>"$results/ref.out" 2>&1 || { echo "the in-process reference scan failed:"; cat "$results/ref.out"; }
grep '^scan' "$results/ref.out" || true
qemu-system-aarch64 -M virt -cpu cortex-a57 -smp 2 -m 1024 -accel tcg,thread=multi -nic none \
  -nographic -no-reboot -kernel "$vmlinuz" -initrd "$initrd" \
  -append "console=ttyAMA0 panic=-1 quiet loglevel=3" \
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
