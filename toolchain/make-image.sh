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
#   toolchain/make-image.sh BOARD OUT_DIR [DEB]
# BOARD: qemu-virt (booted by tests/image/run.sh). DEB: the arm64 package;
# without it, toolchain/make-deb.sh builds it in build/cross-aarch64.
# The root file system's download is cached in build/image-cache.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
here=$root/toolchain/image
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
    ;;
  rpi4 | rpi5)
    echo "make-image: $board: not built yet (qemu-virt is; the Raspberry Pi images need raspi-firmware's boot partition)" >&2
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
# shellcheck source=toolchain/target.sh
. "$root/toolchain/target.sh"

step "host packages"
"$root/scripts/enable-backports.sh" >/dev/null
"$root/toolchain/apt-install-missing.sh" mmdebstrap genimage dosfstools mtools fdisk e2fsprogs kmod cpio xz-utils systemd

if [ -z "$deb" ]; then
  step "the arm64 package"
  "$root/toolchain/install-cross.sh" aarch64
  "$root/toolchain/make-sysroot.sh" aarch64 "$root/build/sysroot-aarch64"
  deb=$("$root/toolchain/make-deb.sh" "$root/build/cross-aarch64" "$root/build/sysroot-aarch64" | tail -n 1)
fi
deb=$(realpath "$deb")
version=$(dpkg-deb -f "$deb" Version)
echo "package: $deb ($version)"

step "root file system"
# The package's run-time dependencies and what a head needs besides: systemd
# and udev, networkd (in systemd), mDNS, SSH (off unless asked for), the
# kernel, busybox for the initramfs, systemd-boot, and the tools that
# image-setup uses. Nothing else: no package manager runs on the head.
packages="$("$root/toolchain/deb-depends.sh" "$deb"),base-passwd,systemd,udev,dbus,kmod,mount,\
util-linux,coreutils,sed,dash,bash,avahi-daemon,openssh-server,busybox-static,systemd-boot-efi,\
linux-image-$kver/bookworm-backports"
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
[ -s "$rootfs/etc/ssh/sshd_config" ] || cp "$rootfs/usr/share/openssh/sshd_config" "$rootfs/etc/ssh/sshd_config"
mkdir -p "$rootfs/data" "$rootfs/boot"
# Every service here has a native unit: without the SysV scripts, systemctl
# does not try to run the target's update-rc.d.
rm -rf "$rootfs/etc/init.d" "$rootfs"/etc/rc?.d
systemctl --root="$rootfs" set-default multi-user.target 2>/dev/null
systemctl --root="$rootfs" enable cylscand.service cylscan-image-setup.service \
  systemd-networkd.service avahi-daemon.service dbus.socket ssh.service 2>/dev/null
# The kernel and its initramfs live on the boot partition; documentation and
# manuals are not read on a head (the copyright files stay). Nor is Mesa's
# rendering: OpenCV's core links libGL for its OpenGL interop, which cylscan
# never calls, so no GL context is made and the DRI drivers (which alone
# link LLVM, 130 MB of the root with it) are never loaded.
mv "$rootfs/boot/vmlinuz-$kver" "$work/vmlinuz"
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
(cd "$ird" && find . | cpio -o -H newc --quiet | gzip -9 >"$work/initrd.img")

step "boot partition"
esp=$work/esp
mkdir -p "$esp/EFI/BOOT" "$esp/loader/entries" "$esp/cylscan-a" "$esp/cylscan"
cp "$rootfs/usr/lib/systemd/boot/efi/systemd-bootaa64.efi" "$esp/EFI/BOOT/BOOTAA64.EFI"
cp "$work/vmlinuz" "$esp/cylscan-a/vmlinuz"
cp "$work/initrd.img" "$esp/cylscan-a/initrd.img"
cat >"$esp/loader/loader.conf" <<EOF
timeout 0
default cylscan-a.conf
editor no
EOF
# rauc.slot names the slot for the initramfs (and RAUC); ro and no GPT
# auto-discovery, so that systemd keeps the root read-only and mounts only
# what fstab lists.
cat >"$esp/loader/entries/cylscan-a.conf" <<EOF
title cylscan $version (slot A)
version $version
linux /cylscan-a/vmlinuz
initrd /cylscan-a/initrd.img
options rauc.slot=a ro systemd.gpt_auto=0 console=$console quiet loglevel=3 systemd.show_status=0 systemd.firstboot=off
EOF
cp "$here/boot-README.txt" "$esp/cylscan/README.txt"

step "file systems"
mib() { echo $(((($1) + 1048575) / 1048576)); }
# The root: its content and a fifth more, so that an update whose root is a
# little larger still fits the other slot.
root_mib=$(($(mib "$(du -sb "$rootfs" | cut -f1)") * 6 / 5 + 32))
mkfs.ext4 -q -F -L "root" -O ^has_journal -m 0 -E root_owner=0:0 -d "$rootfs" "$work/root.ext4" "${root_mib}M"
esp_mib=128
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
    partition-type-uuid = "B921B045-1DF0-41C3-AF44-4C6F280D3FAE"
  }
  partition root-b {
    size = ${root_mib}M
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
size=$(stat -c %s "$out/$name")
used=$(du -B1 "$out/$name" | cut -f1)
echo "image: $out/$name: $(mib "$size") MiB, of which $(mib "$used") MiB hold data (root $root_mib MiB per slot)"
step "done"
