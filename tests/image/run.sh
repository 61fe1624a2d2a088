#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The qemu-virt image booted as a head in the field boots it: through UEFI
# (AAVMF, from Debian's qemu-efi-aarch64) and systemd-boot, on a disk larger
# than the image, with the network behind qemu's user mode. docs/image.md.
#   tests/image/run.sh
# Steps:
#   1. toolchain/make-image.sh qemu-virt build/image (the arm64 package from
#      IMAGE_DEB, else the emulated board's build directory's, else built);
#   2. a copy of the image as the medium, 4 GiB, with a cylscan.toml on its
#      boot partition that picks the virtual head (the image's own board,
#      qemu-virt, needs gpio-sim and vivid, which this image does not load);
#   3. boots it and checks, from outside, what a person who flashed a card
#      finds: the API on port 80 with the token the boot partition holds,
#      the head's name, the booted slot, the data partition grown, SSH off;
#   4. cuts its power, turns SSH on from the boot partition with a key made
#      here, boots it again, and checks that the name and the token are the
#      same, that SSH lets that key in, that the root is read-only and that
#      every unit started;
#   5. updates it through the API (tests/image/updates.sh): bundles made
#      here from the image's own root, a scan kept across them; a bundle
#      signed by another CA and one for another board refused; a new version
#      installed into slot b and booted; a version whose daemon cannot start
#      rolled back to slot b by the boot counter; power cut while RAUC writes
#      a slot, and the head still on its slot with its data.
# Prints "N passed, M failed"; exits non-zero on any failure.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
# shellcheck source=tests/image/updates.sh
. "$root/tests/image/updates.sh"
out=$root/build/image
t0=$SECONDS
step() { printf '\n== image: %s (%ds)\n' "$1" $((SECONDS - t0)); }
passed=0
failed=0
check() { # check NAME COMMAND...: PASS or FAIL
  local name=$1
  shift
  if "$@"; then
    echo "PASS $name"
    passed=$((passed + 1))
  else
    echo "FAIL $name"
    failed=$((failed + 1))
  fi
}
qpid=""
cleanup() {
  if [ -n "$qpid" ]; then
    kill "$qpid" 2>/dev/null || true
    wait "$qpid" 2>/dev/null || true
  fi
  qpid=""
}
trap cleanup EXIT
trap 'cleanup; exit 130' INT TERM

step "image"
deb=${IMAGE_DEB:-}
if [ -z "$deb" ]; then
  deb=$(ls -t "${EMULATED_BUILD_DIR:-$root/build/cross-aarch64}"/package/cylscan_*_arm64.deb 2>/dev/null | head -n 1 || true)
fi
"$root/toolchain/apt-install-missing.sh" qemu-system-arm qemu-efi-aarch64 curl openssh-client e2fsprogs
rm -rf "$out"
"$root/toolchain/make-image.sh" qemu-virt "$out" ${deb:+"$deb"}
img=$(ls "$out"/cylscan-*-qemu-virt.img)
version=$(basename "$img" | sed -e 's/^cylscan-//' -e 's/-qemu-virt\.img$//')

step "the medium"
run=$root/build/image-run
rm -rf "$run"
mkdir -p "$run"
disk=$run/disk.img
cp --sparse=always "$img" "$disk"
image_bytes=$(stat -c %s "$disk")
# The boot partition's offset, for mtools.
boot_offset=$(($(sfdisk -J "$disk" | python3 -c 'import json,sys
t=json.load(sys.stdin)["partitiontable"]
print(next(p["start"] for p in t["partitions"] if p.get("name") == "boot"))') * 512))
printf '[daemon]\nboard = "/usr/share/cylscan/board/sim"\n' >"$run/cylscan.toml"
mcopy -o -i "$disk@@$boot_offset" "$run/cylscan.toml" ::/cylscan/cylscan.toml
truncate -s 4G "$disk"
cp /usr/share/AAVMF/AAVMF_VARS.fd "$run/vars.fd"
step "update bundles"
make_bundles
port=$((20000 + RANDOM % 20000))
ssh_port=$((port + 1))

# boot N: starts qemu; its console in console-N.log.
boot() {
  qemu-system-aarch64 -M virt -cpu cortex-a57 -smp 2 -m 1024 -accel tcg,thread=multi -nographic \
    -drive if=pflash,format=raw,readonly=on,file=/usr/share/AAVMF/AAVMF_CODE.fd \
    -drive if=pflash,format=raw,file="$run/vars.fd" \
    -drive if=virtio,format=raw,file="$disk" \
    -netdev "user,id=n0,hostfwd=tcp:127.0.0.1:$port-:80,hostfwd=tcp:127.0.0.1:$ssh_port-:22" \
    -device virtio-net-pci,netdev=n0,romfile= -device i6300esb \
    </dev/null >"$run/console-$1.log" 2>&1 &
  qpid=$!
}
# Waits for the API (status answers without the token); false after the limit.
api_up() {
  local end=$((SECONDS + ${IMAGE_BOOT_TIMEOUT_S:-420}))
  while [ "$SECONDS" -lt "$end" ]; do
    kill -0 "$qpid" 2>/dev/null || return 1
    if curl -s -m 5 -o /dev/null "http://127.0.0.1:$port/api/v1/status"; then return 0; fi
    sleep 2
  done
  return 1
}
token() { mtype -i "$disk@@$boot_offset" ::/cylscan/api-token.txt 2>/dev/null | tr -d '\r\n'; }
api() { curl -s -m 20 -H "Authorization: Bearer $(token)" "http://127.0.0.1:$port$1"; }
field() { python3 -c 'import json,sys; v=json.load(sys.stdin); [v := v[k] for k in sys.argv[1:]]; print(v)' "$@"; }
not() { ! "$@"; }
# Whether anything answers on the SSH port with an SSH banner.
ssh_answers() {
  local banner
  banner=$(timeout 10 bash -c "exec 3<>/dev/tcp/127.0.0.1/$ssh_port && head -c 7 <&3" 2>/dev/null || true)
  [ "$banner" = "SSH-2.0" ]
}

step "first boot"
boot 1
up=0
api_up && up=1
check "the head boots and its API answers on port 80" test "$up" = 1
[ "$up" = 1 ] || tr -d '\r' <"$run/console-1.log" | tail -n 30
echo "INFO boot 1 answered after $((SECONDS - t0)) s in all"
grep -a 'image-setup:' "$run/console-1.log" | tr -d '\r' | sed 's/^/INFO console: /' || true
tok=$(token)
check "the boot partition holds a 48-digit API token" grep -Eqx '[0-9a-f]{48}' <<<"$tok"
check "the API refuses a request without the token" \
  test "$(curl -s -m 20 -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/api/v1/system")" = 401
system=$(api /api/v1/system || true)
echo "INFO system: $system"
host=$(field hostname <<<"$system" 2>/dev/null || true)
check "the head is named cylscan-XXXXXXXX" grep -Eqx 'cylscan-[0-9a-f]{8}' <<<"$host"
check "it runs the image's version" test "$(field version <<<"$system" 2>/dev/null)" = "$version"
check "it booted slot a" test "$(field slot <<<"$system" 2>/dev/null)" = a
total=$(field data total_bytes <<<"$system" 2>/dev/null || echo 0)
# The medium is 4 GiB and the image $image_bytes: the data partition must
# have grown by the difference (less the file system's own overhead, well
# under a tenth).
check "the data partition grew to fill the medium" \
  test "$total" -gt $(((4 * 1024 * 1024 * 1024 - image_bytes) * 9 / 10))
check "the boot partition's cylscan.toml chose the board" \
  test "$(curl -s -m 20 "http://127.0.0.1:$port/api/v1/status" | field board 2>/dev/null)" = sim
check "SSH is off" not ssh_answers
cleanup

step "second boot, SSH asked for"
# As a person would: a key pair, the public key and the switch on the boot
# partition while the head is off.
ssh-keygen -q -t ed25519 -N '' -f "$run/id" -C image-test
touch "$run/ssh"
mcopy -o -i "$disk@@$boot_offset" "$run/ssh" ::/cylscan/ssh
mcopy -o -i "$disk@@$boot_offset" "$run/id.pub" ::/cylscan/authorized_keys
boot 2
check "the head boots again" api_up
system2=$(api /api/v1/system || true)
check "the token is the same" test "$(token)" = "$tok"
check "the name is the same" test "$(field hostname <<<"$system2" 2>/dev/null)" = "$host"
check "SSH is on" ssh_answers
on_head() {
  ssh -q -i "$run/id" -p "$ssh_port" -o StrictHostKeyChecking=no -o UserKnownHostsFile=/dev/null \
    -o ConnectTimeout=20 root@127.0.0.1 "$@"
}
check "root logs in with the key from the boot partition" test "$(on_head echo in)" = in
check "the root file system is read-only" test "$(on_head findmnt -no OPTIONS / | cut -d, -f1)" = ro
check "every unit started" test "$(on_head systemctl is-system-running --wait)" = running
on_head systemctl --failed --no-legend | sed 's/^/INFO failed unit: /' || true
update_checks

echo "INFO image: $(stat -c %s "$img") bytes, $(du -B1 "$img" | cut -f1) allocated"
echo "image: total $((SECONDS - t0))s"
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
