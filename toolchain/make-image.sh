#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# A flashable cylscan image for a board: OUT_DIR/cylscan-<version>-<board>.img
# (docs/image.md). Debian bookworm's arm64 packages and bookworm-backports'
# kernel, unpacked by mmdebstrap; the partitions made with mkfs and laid out
# by genimage:
#   boot    ESP (FAT): systemd-boot, each slot's kernel and initramfs, the
#           boot entries, and the settings a person may put there (cylscan/)
#   root-a  the root file system, ext4, mounted read-only
#   root-b  the second slot, empty until an update fills it
#   data    ext4: scans, calibrations, the head's identity and token; grown
#           to fill the medium at first boot; updates never touch it
# and the update bundle OUT_DIR/cylscan-<version>-<board>.raucb, whose root
# RAUC writes into the slot not running (toolchain/make-bundle.sh).
#   toolchain/make-image.sh BOARD OUT_DIR [DEB]
# BOARD: qemu-virt (booted by tests/image/run.sh). DEB: the arm64 package;
# without it, toolchain/make-deb.sh builds it in build/cross-aarch64.
# Signing: CYLSCAN_UPDATE_KEYRING (the CA certificate the image trusts),
# CYLSCAN_UPDATE_CERT and CYLSCAN_UPDATE_KEY (a certificate it issued and its
# key, a file or a PKCS#11 URI). Without them, a development CA is made in
# OUT_DIR/dev-keys, fit for tests only (docs/image.md, "Signing keys").
# CYLSCAN_IMAGE_VERSION: the image's version (default: the package's).
# The root file system's download is cached in build/image-cache.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
here=$root/toolchain/image
# shellcheck source=toolchain/target.sh
. "$root/toolchain/target.sh"
usage() {
  echo "usage: toolchain/make-image.sh BOARD OUT_DIR [DEB]   (BOARD: qemu-virt)" >&2
  exit 2
}
if [ $# -lt 2 ] || [ $# -gt 3 ]; then usage; fi
board=$1
out=$(realpath -m "$2")
deb=${3:-}
case $board in
  qemu-virt)
    console=ttyAMA0
    # The drivers the initramfs needs for the boot medium and the root (ext4
    # asks the crypto API for crc32c, which it cannot load by itself there).
    boot_modules="virtio_blk crc32c_generic ext4"
    # A root slot: the root file system (about 770 MiB today) and room for
    # later versions to grow into.
    slot_mib=1024
    ;;
  # Debian's kernel cannot ask the Pi firmware for a trial boot (tryboot is
  # a downstream patch), and on a Pi 5 it has no SD host nor RP1 driver
  # (docs/image.md, "Raspberry Pi: what Debian's kernel allows").
  rpi4)
    echo "make-image: rpi4: not built yet: Debian's kernel cannot set the Pi firmware's tryboot flag, so the image has no fail-safe update yet (docs/image.md, \"Raspberry Pi\")" >&2
    exit 2
    ;;
  rpi5)
    echo "make-image: rpi5: not built: Debian's $kabi kernel has no driver for the Pi 5's SD card (MMC_SDHCI_BRCMSTB) nor for RP1, which carries its GPIO header (docs/image.md, \"Raspberry Pi\")" >&2
    exit 2
    ;;
  *)
    echo "make-image: $board: no such board (qemu-virt)" >&2
    exit 2
    ;;
esac
[ -d "$root/board/$board" ] || { echo "make-image: board/$board is missing" >&2; exit 2; }
if [ -n "$deb" ] && [ ! -f "$deb" ]; then
  echo "make-image: $deb: no such package" >&2
  exit 2
fi
cache=${IMAGE_CACHE:-$root/build/image-cache}
mkdir -p "$cache" "$out"
t0=$SECONDS
step() { printf '== make-image: %s (%ds)\n' "$1" $((SECONDS - t0)); }

step "host packages"
"$root/scripts/enable-backports.sh" >/dev/null
"$root/toolchain/apt-install-missing.sh" mmdebstrap genimage dosfstools mtools fdisk e2fsprogs kmod cpio xz-utils systemd \
  rauc squashfs-tools openssl

if [ -z "$deb" ]; then
  step "the arm64 package"
  "$root/toolchain/install-cross.sh" aarch64
  "$root/toolchain/make-sysroot.sh" aarch64 "$root/build/sysroot-aarch64"
  deb=$("$root/toolchain/make-deb.sh" "$root/build/cross-aarch64" "$root/build/sysroot-aarch64" | tail -n 1)
fi
deb=$(realpath "$deb")
version=${CYLSCAN_IMAGE_VERSION:-$(dpkg-deb -f "$deb" Version)}
echo "package: $deb, image version $version"

step "signing keys"
keyring=${CYLSCAN_UPDATE_KEYRING:-}
sign_cert=${CYLSCAN_UPDATE_CERT:-}
sign_key=${CYLSCAN_UPDATE_KEY:-}
if [ -z "$keyring" ]; then
  [ -z "$sign_cert$sign_key" ] || { echo "make-image: CYLSCAN_UPDATE_CERT/KEY need CYLSCAN_UPDATE_KEYRING" >&2; exit 2; }
  echo "make-image: no CYLSCAN_UPDATE_KEYRING: a development CA in $out/dev-keys (tests only)" >&2
  "$root/toolchain/make-dev-keys.sh" "$out/dev-keys" >/dev/null
  keyring=$out/dev-keys/ca.cert.pem
  sign_cert=$out/dev-keys/signing.cert.pem
  sign_key=$out/dev-keys/signing.key.pem
fi
[ -f "$keyring" ] || { echo "make-image: $keyring: no such keyring" >&2; exit 2; }

step "root file system"
# The package's run-time dependencies and what a head needs besides: systemd
# and udev, networkd (in systemd), mDNS, SSH (off unless asked for), the
# kernel, busybox for the initramfs, systemd-boot, and the tools that
# image-setup uses. Nothing else: no package manager runs on the head.
packages="$("$root/toolchain/deb-depends.sh" "$deb"),base-passwd,systemd,udev,dbus,kmod,mount,\
util-linux,coreutils,sed,dash,bash,avahi-daemon,openssh-server,busybox-static,systemd-boot-efi,\
systemd-boot,rauc,rauc-service,e2fsprogs,linux-image-$kver/bookworm-backports"
base=$cache/rootfs-$board
if [ ! -f "$base.stamp" ] || [ "$(cat "$base.stamp")" != "$packages" ]; then
  rm -rf "$base" "$base.stamp"
  mmdebstrap --mode=root --arch=arm64 --variant=extract --include="$packages" bookworm "$base" \
    "deb $mirror bookworm main" "deb $mirror bookworm-updates main" \
    "deb $mirror bookworm-backports main"
  echo "$packages" >"$base.stamp"
fi
work=$cache/work-$board
rm -rf "$work"
mkdir -p "$work"
rootfs=$work/root
cp -a "$base" "$rootfs"
dpkg-deb -x "$deb" "$rootfs"
cp -a "$here/rootfs/." "$rootfs/"
"$root/toolchain/rootfs-fixups.sh" "$rootfs"
# The accounts of the packages (cylscan's, systemd's, dbus's and, from the
# image's own sysusers.d file, avahi's and sshd's): made here, since the
# root is read-only on the head.
systemd-sysusers --root="$rootfs" >/dev/null
# Empty: the initramfs binds the head's own over them.
: >"$rootfs/etc/machine-id"
: >"$rootfs/etc/hostname"
echo "$board" >"$rootfs/usr/lib/cylscan/image-board"
# The image's name and version, where os-release(5) puts them.
printf 'IMAGE_ID=cylscan-%s\nIMAGE_VERSION=%s\n' "$board" "$version" >>"$rootfs/usr/lib/os-release"
# RAUC: the two root slots, this board's compatible string, the keyring,
# systemd-boot through the image's backend, and its status on /data.
mkdir -p "$rootfs/etc/rauc"
cp "$keyring" "$rootfs/etc/rauc/keyring.pem"
cat >"$rootfs/etc/rauc/system.conf" <<EOF
[system]
compatible=cylscan-$board
bootloader=custom
data-directory=/data/rauc
bundle-formats=verity

[keyring]
path=/etc/rauc/keyring.pem

[handlers]
bootloader-custom-backend=/usr/lib/cylscan/rauc-boot

[slot.rootfs.0]
device=/dev/disk/by-partlabel/root-a
type=ext4
bootname=a

[slot.rootfs.1]
device=/dev/disk/by-partlabel/root-b
type=ext4
bootname=b
EOF
[ -s "$rootfs/etc/ssh/sshd_config" ] || cp "$rootfs/usr/share/openssh/sshd_config" "$rootfs/etc/ssh/sshd_config"
mkdir -p "$rootfs/data" "$rootfs/boot"
# Every service here has a native unit: without the SysV scripts, systemctl
# does not try to run the target's update-rc.d.
rm -rf "$rootfs/etc/init.d" "$rootfs"/etc/rc?.d
systemctl --root="$rootfs" set-default multi-user.target 2>/dev/null
systemctl --root="$rootfs" enable cylscand.service cylscan-image-setup.service \
  cylscan-selftest.service cylscan-update-reboot.path \
  systemd-networkd.service avahi-daemon.service dbus.socket ssh.service 2>/dev/null
# The kernel and its initramfs boot from the boot partition, where
# rauc-boot copies them from the slot's /usr/lib/cylscan/boot; documentation
# and manuals are not read on a head (the copyright files stay). Nor is Mesa's
# rendering: OpenCV's core links libGL for its OpenGL interop, which cylscan
# never calls, so no GL context is made and the DRI drivers (which alone
# link LLVM, 130 MB of the root with it) are never loaded.
slotboot=$rootfs/usr/lib/cylscan/boot
mkdir -p "$slotboot"
mv "$rootfs/boot/vmlinuz-$kver" "$slotboot/vmlinuz"
# The kernel command line after rauc.slot=: ro and no GPT auto-discovery, so
# that systemd keeps the root read-only and mounts only what fstab lists;
# panic=10 reboots a kernel that panics, which counts as a failed try.
echo "ro systemd.gpt_auto=0 console=$console panic=10 quiet loglevel=3 systemd.show_status=0 systemd.firstboot=off" \
  >"$slotboot/options"
rm -rf "${rootfs:?}"/boot/* "$rootfs"/usr/share/man "$rootfs"/usr/share/info
find "$rootfs/usr/share/doc" -type f ! -name copyright -delete
rm -rf "$rootfs/usr/lib/aarch64-linux-gnu/dri" "$rootfs"/usr/lib/aarch64-linux-gnu/libLLVM-*.so*

step "initramfs"
ird=$work/initramfs
mkdir -p "$ird"/{bin,dev,proc,sys,newroot,modules}
cp "$rootfs/bin/busybox" "$ird/bin/busybox"
# The boot modules and what they depend on, in the order they load
# (modules.dep lists a module's dependencies, nearest first).
moddir=$rootfs/lib/modules/$kver
: >"$ird/modules/order"
add_module() {
  local name=$1 path dep
  path=$(sed -n "s|^\(\([^:]*/\)\?$name\.ko\(\.xz\)\?\):.*|\1|p" "$moddir/modules.dep" | head -n 1)
  [ -n "$path" ] || { echo "make-image: module $name not found" >&2; return 1; }
  grep -qx "$name" "$ird/modules/order" && return 0
  for dep in $(sed -n "s|^$path: *||p" "$moddir/modules.dep" | tr ' ' '\n' | tac); do
    dep=$(basename "$dep" | sed -e 's/\.xz$//' -e 's/\.ko$//')
    add_module "$dep"
  done
  grep -qx "$name" "$ird/modules/order" && return 0
  xz -dc "$moddir/$path" >"$ird/modules/$name.ko"
  echo "$name" >>"$ird/modules/order"
}
for m in $boot_modules; do add_module "$m"; done
cp "$here/initramfs-init" "$ird/init"
chmod +x "$ird/init"
(cd "$ird" && find . | cpio -o -H newc --quiet | gzip -9 >"$slotboot/initrd.img")

step "boot partition"
esp=$work/esp
mkdir -p "$esp/EFI/BOOT" "$esp/loader/entries" "$esp/cylscan-a" "$esp/cylscan"
cp "$rootfs/usr/lib/systemd/boot/efi/systemd-bootaa64.efi" "$esp/EFI/BOOT/BOOTAA64.EFI"
cp "$slotboot/vmlinuz" "$slotboot/initrd.img" "$esp/cylscan-a/"
# No default: systemd-boot boots the first entry in its order, which
# rauc-boot keeps (usr/lib/cylscan/rauc-boot).
cat >"$esp/loader/loader.conf" <<EOF
timeout 0
editor no
EOF
# rauc.slot names the slot for the initramfs (and RAUC). Slot A as flashed
# is good: no tries counted; generation 1.
cat >"$esp/loader/entries/cylscan-a.conf" <<EOF
title cylscan $version (slot A)
sort-key cylscan
version 1
linux /cylscan-a/vmlinuz
initrd /cylscan-a/initrd.img
options rauc.slot=a $(cat "$slotboot/options")
EOF
cp "$here/boot-README.txt" "$esp/cylscan/README.txt"

step "file systems"
mib() { echo $(((($1) + 1048575) / 1048576)); }
# The root file system: its content and a fifth more. Each slot partition is
# a fixed size, so that every later update's root fits it: RAUC refuses an
# image larger than its slot, and the partitions of a head in the field are
# never moved.
root_mib=$(($(mib "$(du -sb "$rootfs" | cut -f1)") * 6 / 5 + 32))
if [ "$root_mib" -gt "$slot_mib" ]; then
  echo "make-image: the root needs $root_mib MiB, more than a slot's $slot_mib MiB" >&2
  exit 1
fi
mkfs.ext4 -q -F -L "root" -O ^has_journal -m 0 -E root_owner=0:0 -d "$rootfs" "$work/root.ext4" "${root_mib}M"
# Two slots' kernels (44 MiB each on qemu-virt, uncompressed) and
# initramfs, and room for a third while one is replaced.
esp_mib=256
rm -f "$work/boot.vfat"
mkfs.vfat -n BOOT -F 32 -C "$work/boot.vfat" $((esp_mib * 1024)) >/dev/null
mcopy -s -i "$work/boot.vfat" "$esp"/* ::/
# The data partition as flashed: small, with the daemon's folder owned by its
# user; it grows at first boot.
data=$work/data
mkdir -p "$data/cylscan"
uid=$(awk -F: '$1 == "cylscan" {print $3}' "$rootfs/etc/passwd")
gid=$(awk -F: '$1 == "cylscan" {print $4}' "$rootfs/etc/passwd")
chown "$uid:$gid" "$data/cylscan"
chmod 0750 "$data/cylscan"
# RAUC's status of the slots (system.conf's data-directory), root's alone.
mkdir -p "$data/rauc"
chmod 0700 "$data/rauc"
mkfs.ext4 -q -F -L data -E root_owner=0:0 -d "$data" "$work/data.ext4" 64M

step "disk image"
name=cylscan-$version-$board.img
cat >"$work/genimage.cfg" <<EOF
image $name {
  hdimage {
    partition-table-type = "gpt"
  }
  partition boot {
    image = "boot.vfat"
    partition-type-uuid = "C12A7328-F81F-11D2-BA4B-00A0C93EC93B"
    offset = 1M
  }
  partition root-a {
    image = "root.ext4"
    size = ${slot_mib}M
    partition-type-uuid = "B921B045-1DF0-41C3-AF44-4C6F280D3FAE"
  }
  partition root-b {
    size = ${slot_mib}M
    partition-type-uuid = "B921B045-1DF0-41C3-AF44-4C6F280D3FAE"
  }
  partition data {
    image = "data.ext4"
    partition-type-uuid = "0FC63DAF-8483-4772-8E79-3D69D8477DE4"
  }
}
EOF
rm -rf "$work/genimage-tmp" "$work/genimage-root" "${out:?}/$name"
mkdir -p "$work/genimage-root"
genimage --config "$work/genimage.cfg" --rootpath "$work/genimage-root" --tmppath "$work/genimage-tmp" \
  --inputpath "$work" --outputpath "$out" >"$work/genimage.log" 2>&1 ||
  { cat "$work/genimage.log" >&2; exit 1; }
rm -rf "$rootfs" "$work/genimage-tmp"

step "update bundle"
CYLSCAN_UPDATE_CERT=$sign_cert CYLSCAN_UPDATE_KEY=$sign_key CYLSCAN_UPDATE_KEYRING=$keyring \
  "$root/toolchain/make-bundle.sh" "$work/root.ext4" "$board" "$version" "$out/cylscan-$version-$board.raucb"
size=$(stat -c %s "$out/$name")
used=$(du -B1 "$out/$name" | cut -f1)
echo "image: $out/$name: $(mib "$size") MiB, of which $(mib "$used") MiB hold data (root $root_mib MiB in slots of $slot_mib MiB)"
echo "bundle: $out/cylscan-$version-$board.raucb: $(mib "$(stat -c %s "$out/cylscan-$version-$board.raucb")") MiB"
step "done"
