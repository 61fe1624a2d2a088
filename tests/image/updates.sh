# SPDX-License-Identifier: Apache-2.0
# shellcheck shell=bash
# shellcheck disable=SC2154 # img, run, out, root, version, port, t0: run.sh's
# Sourced by tests/image/run.sh: A/B updates of the booted image through the
# API (docs/image.md, "Updates"). make_bundles runs on the host before the
# boots; update_checks on the running head (SSH on), which it leaves off.
# The bundles are made here from the image's own root slot, as a maker
# would make the next release's, and signed with the image's development
# keys (or, for the refusal, another CA's):
#   next     IMAGE_VERSION $version-next: the update that must land;
#   broken   $version-broken, whose cylscand exits at once: must roll back;
#   stranger for cylscan-rpi4: refused;
#   forged   signed by a CA the head does not trust: refused.

# The root file system of the image's slot A, as an ext4 file.
image_root() { # image_root OUT
  local start size blocks bsize
  read -r start size < <(sfdisk -J "$img" | python3 -c 'import json,sys
t=json.load(sys.stdin)["partitiontable"]
p=next(p for p in t["partitions"] if p.get("name") == "root-a")
print(p["start"] * 512, p["size"] * 512)')
  dd if="$img" of="$1" bs=4M iflag=skip_bytes,count_bytes skip="$start" count="$size" \
    conv=sparse status=none
  # Only the file system, not the rest of the slot.
  blocks=$(dumpe2fs -h "$1" 2>/dev/null | sed -n 's/^Block count: *//p')
  bsize=$(dumpe2fs -h "$1" 2>/dev/null | sed -n 's/^Block size: *//p')
  truncate -s $((blocks * bsize)) "$1"
}
# Replaces a file of an ext4 root by a host file (its mode kept).
put_file() { # put_file ROOT_EXT4 HOST_FILE PATH
  debugfs -w -R "rm $3" "$1" >/dev/null 2>&1
  debugfs -w -R "write $2 $3" "$1" >/dev/null 2>&1
  [ "$(debugfs -R "cat $3" "$1" 2>/dev/null | sha256sum)" = "$(sha256sum <"$2")" ]
}
# A copy of the root that says it is VERSION.
versioned_root() { # versioned_root OUT VERSION
  cp --sparse=always "$run/root.ext4" "$1"
  debugfs -R "cat /usr/lib/os-release" "$1" 2>/dev/null |
    sed "s/^IMAGE_VERSION=.*/IMAGE_VERSION=$2/" >"$run/os-release"
  chmod 0644 "$run/os-release"
  put_file "$1" "$run/os-release" /usr/lib/os-release
}
sign_with() { # sign_with KEYDIR ROOT BOARD VERSION OUT
  CYLSCAN_UPDATE_CERT=$1/signing.cert.pem CYLSCAN_UPDATE_KEY=$1/signing.key.pem \
    "$root/toolchain/make-bundle.sh" "$2" "$3" "$4" "$5" >/dev/null
}

make_bundles() {
  local keys=$out/dev-keys
  next_version=$version-next
  broken_version=$version-broken
  image_root "$run/root.ext4"
  versioned_root "$run/next.ext4" "$next_version"
  sign_with "$keys" "$run/next.ext4" qemu-virt "$next_version" "$run/next.raucb"
  rm -f "$run/next.ext4"
  versioned_root "$run/broken.ext4" "$broken_version"
  printf '#!/bin/sh\necho "cylscand: this build is broken on purpose" >&2\nexit 1\n' >"$run/cylscand-broken"
  chmod 0755 "$run/cylscand-broken"
  put_file "$run/broken.ext4" "$run/cylscand-broken" /usr/bin/cylscand
  sign_with "$keys" "$run/broken.ext4" qemu-virt "$broken_version" "$run/broken.raucb"
  rm -f "$run/broken.ext4" "$run/root.ext4"
  # The refusals need no real root: RAUC refuses before it reads one. Some
  # random content, since RAUC wants a squashfs of more than one block.
  mkdir -p "$run/small"
  head -c 65536 /dev/urandom >"$run/small/noise"
  mkfs.ext4 -q -F -d "$run/small" "$run/small.ext4" 4M
  sign_with "$keys" "$run/small.ext4" rpi4 "$version" "$run/stranger.raucb"
  "$root/toolchain/make-dev-keys.sh" "$run/forger-keys" >/dev/null
  sign_with "$run/forger-keys" "$run/small.ext4" qemu-virt "$version" "$run/forged.raucb"
  local b
  for b in "$run"/*.raucb; do echo "INFO bundle: $(basename "$b"): $(stat -c %s "$b") bytes"; done
}

# PUT a bundle; prints the HTTP status, the answer in $run/put.json.
put_bundle() {
  curl -s -m 900 -o "$run/put.json" -w '%{http_code}' -T "$1" \
    -H "Authorization: Bearer $(token)" -H 'Content-Type: application/octet-stream' \
    "http://127.0.0.1:$port/api/v1/system/update"
}
system_json() { api /api/v1/system 2>/dev/null || true; }
# The update's field: update_field state | progress | last result ...
update_field() { system_json | field update "$@" 2>/dev/null || true; }
slot_field() { # slot_field BOOTNAME KEY: that slot's KEY in GET /api/v1/system
  system_json | python3 -c 'import json,sys
s=json.load(sys.stdin)
print(next(x for x in s["slots"] if x["bootname"] == sys.argv[1])[sys.argv[2]])' "$1" "$2" 2>/dev/null || true
}
# The update's state, progress and message on one line ("- 0 -" when the
# API does not answer).
update_line() {
  system_json | python3 -c 'import json,sys
u=json.load(sys.stdin)["update"]
print(u["state"], u["progress"], u["message"])' 2>/dev/null || echo "- 0 -"
}
# Waits until the install is over: installed or failed, or the head already
# gone down to reboot into it (the install can end and the reboot begin
# between two looks); false after the limit.
install_ends() {
  local end=$((SECONDS + 900)) r
  while [ "$SECONDS" -lt "$end" ]; do
    curl -s -m 5 -o /dev/null "http://127.0.0.1:$port/api/v1/status" || return 0
    r=$(update_field last result)
    if [ "$(update_field state)" = idle ] && { [ "$r" = installed ] || [ "$r" = failed ]; }; then
      return 0
    fi
    sleep 1
  done
  return 1
}
# Waits for the API to stop answering (the head reboots); false after the limit.
api_down() {
  local end=$((SECONDS + 300))
  while [ "$SECONDS" -lt "$end" ]; do
    curl -s -m 5 -o /dev/null "http://127.0.0.1:$port/api/v1/status" || return 0
    sleep 1
  done
  return 1
}
entries() { on_head ls /boot/loader/entries | tr '\n' ' '; }
# Waits until slot's boot entry has been blessed (its try counter dropped).
blessed() { # blessed BOOTNAME
  local _
  for _ in $(seq 1 60); do
    on_head test -e "/boot/loader/entries/cylscan-$1.conf" && return 0
    sleep 2
  done
  return 1
}
# Sends the first 8 MiB of a bundle under its whole Content-Length, and
# hangs up: an upload cut off.
cut_upload() { # cut_upload BUNDLE
  python3 - "$port" "$(token)" "$1" <<'PY'
import os
import socket
import sys

port, token, path = int(sys.argv[1]), sys.argv[2], sys.argv[3]
head = (f"PUT /api/v1/system/update HTTP/1.1\r\nHost: head\r\n"
        f"Authorization: Bearer {token}\r\nContent-Type: application/octet-stream\r\n"
        f"Content-Length: {os.path.getsize(path)}\r\n\r\n")
with socket.create_connection(("127.0.0.1", port), timeout=30) as s, open(path, "rb") as f:
    s.sendall(head.encode())
    s.sendall(f.read(8 << 20))
PY
}
# Waits until the last update's record says RESULT; false after a minute.
last_result_is() { # last_result_is RESULT
  local _
  for _ in $(seq 1 30); do
    [ "$(update_field state)" = idle ] && [ "$(update_field last result)" = "$1" ] && return 0
    sleep 2
  done
  return 1
}
# The head as the API reports it after a boot: its slot, the image's version
# and the last update's result, each a check.
head_reports() { # head_reports WHEN SLOT VERSION RESULT
  local system
  system=$(system_json)
  echo "INFO system $1: $system"
  check "$1: it runs slot $2" test "$(field slot <<<"$system" 2>/dev/null)" = "$2"
  check "$1: it runs $3" test "$(field image version <<<"$system" 2>/dev/null)" = "$3"
  check "$1: the API reports the update $4" \
    test "$(field update last result <<<"$system" 2>/dev/null)" = "$4"
}
# Whether systemd-bless-boot marked this boot's counted entry good (it logs
# nothing when the entry was not counting).
bless_logged() { on_head journalctl -b -u systemd-bless-boot -o cat | grep -q "Marked boot as 'good'"; }
# The files of a scan, by their digests.
scan_digests() { # scan_digests ID
  local f
  for f in scan.json texture.png phase.png; do
    printf '%s %s\n' "$f" "$(api "/api/v1/scans/$1/$f" | sha256sum | cut -d' ' -f1)"
  done
}
# Everything on the data partition, by content and name (the update's own
# folder aside, which an update is allowed to change).
data_digest() {
  # busybox's find and xargs: the image has no findutils.
  on_head "cd /data && busybox find . -path ./cylscan/update -prune -o -path ./rauc -prune -o -type f -print0 |
    sort -z | busybox xargs -0 sha256sum" | sha256sum | cut -d' ' -f1
}

update_checks() {
  step "a scan before the update"
  local id
  id=$(curl -s -m 20 -X POST -H "Authorization: Bearer $(token)" -H 'Content-Type: application/json' \
    --data '{}' "http://127.0.0.1:$port/api/v1/scans" | field id 2>/dev/null || true)
  local end=$((SECONDS + 900)) state=""
  while [ -n "$id" ] && [ "$SECONDS" -lt "$end" ]; do
    state=$(api "/api/v1/scans/$id" | field state 2>/dev/null || true)
    case $state in done | failed) break ;; esac
    sleep 3
  done
  check "a scan on the image is done" test "$state" = "done"
  echo "INFO scan $id: $state after $((SECONDS - t0)) s in all"
  scan_digests "$id" >"$run/scan-before.txt"

  step "refused bundles"
  local before_entries before_slots
  before_entries=$(entries)
  before_slots=$(system_json | field slots)
  check "a bundle signed by an unknown CA is refused (422)" test "$(put_bundle "$run/forged.raucb")" = 422
  echo "INFO refusal: $(cat "$run/put.json")"
  check "a bundle for another board is refused (422)" test "$(put_bundle "$run/stranger.raucb")" = 422
  echo "INFO refusal: $(cat "$run/put.json")"
  check "it names both boards" grep -q 'cylscan-rpi4.*cylscan-qemu-virt' "$run/put.json"
  check "the refusals changed no boot entry" test "$(entries)" = "$before_entries"
  check "the refusals changed no slot" test "$(system_json | field slots)" = "$before_slots"
  check "the refusals left no bundle and no record" \
    test "$(on_head ls -A /var/lib/cylscan/update 2>/dev/null | tr '\n' ' ')" = ""
  # A data partition too full for the bundle: 507 before a byte is stored.
  local free
  free=$(system_json | field data free_bytes 2>/dev/null || echo 0)
  on_head fallocate -l $((free - 100 * 1024 * 1024)) /data/cylscan/filler
  check "a bundle that does not fit the data partition is refused (507)" \
    test "$(put_bundle "$run/next.raucb")" = 507
  echo "INFO refusal: $(cat "$run/put.json")"
  on_head rm -f /data/cylscan/filler
  check "the full partition left no bundle and no record" \
    test "$(on_head ls -A /var/lib/cylscan/update 2>/dev/null | tr '\n' ' ')" = ""
  cut_upload "$run/next.raucb"
  check "an upload cut off is recorded failed" last_result_is failed
  echo "INFO cut off: $(update_field last message)"
  check "it left nothing but the record" \
    test "$(on_head ls -A /var/lib/cylscan/update 2>/dev/null | tr '\n' ' ')" = "last.json "
  check "and changed no boot entry" test "$(entries)" = "$before_entries"

  step "an update through the API"
  local data_before
  data_before=$(data_digest)
  check "the new version's bundle is accepted (202)" test "$(put_bundle "$run/next.raucb")" = 202
  echo "INFO accepted: $(cat "$run/put.json")"
  check "it installs into slot b" test "$(field target_slot <"$run/put.json" 2>/dev/null)" = b
  check "the install ends" install_ends
  echo "INFO install ended after $((SECONDS - t0)) s in all"
  check "the head reboots by itself" api_down
  check "it comes back" api_up
  head_reports "after the update" b "$next_version" booted
  check "slot b is blessed once cylscand is up" blessed b
  check "it was on trial: systemd-bless-boot marked the try good" bless_logged
  echo "INFO entries: $(entries)"
  check "RAUC reports slot b booted and good" \
    test "$(slot_field b state) $(slot_field b boot_status)" = "booted good"
  scan_digests "$id" >"$run/scan-after-update.txt"
  check "the scan is still there, byte for byte" cmp -s "$run/scan-before.txt" "$run/scan-after-update.txt"
  check "nothing else on the data partition changed" test "$(data_digest)" = "$data_before"

  step "an update whose daemon cannot start"
  check "the broken bundle is accepted (202)" test "$(put_bundle "$run/broken.raucb")" = 202
  check "its install ends" install_ends
  check "the head reboots into it" api_down
  # Two tries on slot a, each a boot and a self-test that fails, then slot b.
  IMAGE_BOOT_TIMEOUT_S=900 api_up
  head_reports "back by itself" b "$next_version" "rolled back"
  check "RAUC reports slot a bad" test "$(slot_field a boot_status)" = bad
  grep -a 'cylscan-selftest' "$run/console-2.log" | tr -d '\r' | sed 's/^/INFO console: /' | tail -n 6 || true
  echo "INFO entries: $(entries)"

  step "power cut during an update"
  data_before=$(data_digest)
  check "the first version's bundle is accepted (202)" \
    test "$(put_bundle "$out/cylscan-$version-qemu-virt.raucb")" = 202
  # Cut while RAUC copies the root into slot a: as soon as its progress
  # message says so (the copy then lasts tens of seconds under emulation).
  local cut=0
  end=$((SECONDS + 600))
  while [ "$SECONDS" -lt "$end" ]; do
    local state progress message
    read -r state progress message < <(update_line)
    if [ "$state" = installing ] && [[ $message == "Copying image"* ]]; then
      kill -9 "$qpid"
      echo "INFO power cut at $progress %: $message"
      wait "$qpid" 2>/dev/null || true
      qpid=""
      cut=1
      break
    fi
    sleep 0.5
  done
  check "the power was cut during the install" test "$cut" = 1
  cleanup
  boot 3
  check "the head boots after the cut" api_up
  head_reports "after the cut" b "$next_version" failed
  scan_digests "$id" >"$run/scan-after-cut.txt"
  check "the scan is still there, byte for byte" cmp -s "$run/scan-before.txt" "$run/scan-after-cut.txt"
  check "nothing else on the data partition changed" test "$(data_digest)" = "$data_before"
  check "every unit started" test "$(on_head systemctl is-system-running --wait)" = running
  on_head systemctl --failed --no-legend | sed 's/^/INFO failed unit: /' || true
  cleanup
}
