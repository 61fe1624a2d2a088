#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Counts the instructions per pixel of the phase engine's fold and finalize on
# an ARM target, under qemu-user, and estimates a Cortex-A76's frame rate:
#   bench/instructions/count.sh [aarch64|armhf] [auto|baseline]
# (defaults aarch64, auto: the widest kernels the emulated CPU runs; baseline:
# the target's baseline build of them, e.g. armhf's without NEON).
# Needs the cross build of scripts/cross-test.sh (CROSS_BUILD_DIR, default
# build/cross-<arch>, and its sysroot build/sysroot-<arch>); it builds the
# cylscan_kernel_work target there.
#
# How: qemu runs one instruction per translation block (-singlestep) and logs
# every block it executes (-d nochain,exec), filtered (-dfilter) to the
# program's own code except its driver (main and the frame synthesis): the
# engine and what it inlines. Calls into shared libraries (libc's memchr and
# memset, OpenCV's allocations) are not counted; at 64x48 they added 1.2 % to
# the finalize. cylscan_kernel_work does setup, setup+fold or
# setup+fold+finalize; the differences are each stage's count. The finalize
# has a part proportional to the pixels and a part that is not (the order
# residual is measured on a sample of about 8192 pixels), so two sizes give
# both, and 1000x800 is extrapolated from them.
set -euo pipefail
arch=${1:-aarch64}
isa=${2:-auto}
case "$isa" in
  auto | baseline) ;;
  *) echo "usage: $0 [aarch64|armhf] [auto|baseline]" >&2; exit 2 ;;
esac
case "$arch" in
  aarch64) qemu=qemu-aarch64 nm=aarch64-linux-gnu-nm ;;
  armhf) qemu=qemu-arm nm=arm-linux-gnueabihf-nm ;;
  *) echo "usage: $0 [aarch64|armhf] [auto|baseline]" >&2; exit 2 ;;
esac
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${CROSS_BUILD_DIR:-$root/build/cross-$arch}
sysroot=$root/build/sysroot-$arch
if [ ! -f "$build/CMakeCache.txt" ] || [ ! -d "$sysroot/usr" ]; then
  echo "count.sh: no cross build in $build or no sysroot in $sysroot; run scripts/cross-test.sh $arch first" >&2
  exit 2
fi
for tool in "$qemu" "$nm"; do
  command -v "$tool" >/dev/null || { echo "count.sh: $tool is missing (toolchain/install-cross.sh $arch)" >&2; exit 2; }
done
cmake --build "$build" --target cylscan_kernel_work >/dev/null
program=$build/bench/instructions/cylscan_kernel_work

# The address ranges of every function but the driver's, merged.
ranges=$("$nm" -C -S --defined-only "$program" | python3 -c '
import sys
spans = []
for line in sys.stdin:
    f = line.rstrip("\n").split(" ", 3)
    if len(f) < 4 or f[2] not in "tTwW":
        continue
    name = f[3]
    if name == "main" or name.startswith("(anonymous namespace)::"):
        continue
    start = int(f[0], 16)
    spans.append((start, start + int(f[1], 16)))
spans.sort()
merged = []
for a, b in spans:
    if merged and a <= merged[-1][1] + 16:
        merged[-1] = (merged[-1][0], max(merged[-1][1], b))
    else:
        merged.append((a, b))
print(",".join(f"0x{a:x}..0x{b - 1:x}" for a, b in merged))')

count() {  # WIDTH HEIGHT STAGE -> instructions executed in the counted code
  "$qemu" -L "$sysroot" -singlestep -d nochain,exec -dfilter "$ranges" -D /dev/fd/3 \
    "$program" "$1" "$2" "$3" "$isa" 3>&1 1>/dev/null | grep -c '^Trace'
}

sizes=("256 128" "512 128")
declare -A n
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for size in "${sizes[@]}"; do
  for stage in setup fold finalize; do
    # shellcheck disable=SC2086 # "W H" is two arguments
    (count $size "$stage" >"$tmp/${size/ /x}-$stage") &
  done
  wait
done
for size in "${sizes[@]}"; do
  for stage in setup fold finalize; do n[${size/ /x}-$stage]=$(cat "$tmp/${size/ /x}-$stage"); done
done

python3 - "${n[256x128-setup]}" "${n[256x128-fold]}" "${n[256x128-finalize]}" \
  "${n[512x128-setup]}" "${n[512x128-fold]}" "${n[512x128-finalize]}" "$arch $isa" <<'PY'
import sys
s1, f1, z1, s2, f2, z2 = (int(v) for v in sys.argv[1:7])
arch = sys.argv[7]
p1, p2 = 256 * 128, 512 * 128
frames = 50
fold = [(f1 - s1) / (frames * p1), (f2 - s2) / (frames * p2)]
fin = [z1 - f1, z2 - f2]
slope = (fin[1] - fin[0]) / (p2 - p1)
fixed = fin[0] - slope * p1
px = 1000 * 800
fold_px = fold[1]
fold_frame = fold_px * px
fin_scan = slope * px + fixed
print(f"instructions ({arch}, counted under qemu-user):")
print(f"  fold: {fold[0]:.2f} and {fold[1]:.2f} per pixel and frame at 256x128 and 512x128")
print(f"  finalize: {fin[0] / p1:.1f} and {fin[1] / p2:.1f} per pixel at 256x128 and 512x128;"
      f" {slope:.1f} per pixel + {fixed / 1e6:.2f} M per scan")
print(f"at 1000x800: fold {fold_frame / 1e6:.2f} M per frame, finalize {fin_scan / 1e6:.1f} M per scan")
ghz = 2.4
print(f"Cortex-A76 at {ghz} GHz, one core, if it sustains IPC instructions per cycle:")
print("  IPC  fold/frame  fps (fold only)  scan of 2x25 (fold+finalize)  fps with finalize shared")
for ipc in (1.5, 2.0, 3.0):
    t_fold = fold_frame / (ipc * ghz * 1e9)
    t_fin = fin_scan / (ipc * ghz * 1e9)
    per_frame = t_fold + t_fin / frames
    print(f"  {ipc:.1f}  {t_fold * 1e3:7.2f} ms  {1 / t_fold:10.0f}  {(frames * t_fold + t_fin) * 1e3:17.1f} ms"
          f"  {1 / per_frame:18.0f}")
print("memory: the fold reads a frame byte and reads and writes 12 B of sums per pixel,")
print(f"  25 B/pixel: {25 * px / 1e6:.0f} MB per frame, {25 * px * 120 / 1e9:.1f} GB/s at 120 fps")
PY
