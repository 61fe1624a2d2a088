#!/bin/busybox sh
# SPDX-License-Identifier: Apache-2.0
# Runs in the emulated board as a systemd service (emulated-board.service,
# started by the boot target emulated-board.target; run.sh boots the guest):
# sets up gpio-sim with the lines of board/qemu-virt/board.toml and vivid
# with output-to-capture loopback (the firmware's camera), checks them, the
# installed package and what udev and systemd made of it, then runs the scans
# through cylscand (guest-scan.sh).
# Each check prints one "PASS <what>" or "FAIL <what>: <why>" line on the
# console; run.sh counts them. /results is the host's results directory.
export PATH=/usr/sbin:/usr/bin:/sbin:/bin
bb=/bin/busybox
board=/usr/share/cylscan/board/qemu-virt
res=/results
kver=$(uname -r)
pass() { echo "PASS $1"; }
fail() { echo "FAIL $1"; }
check() { # check WHAT COMMAND...
  what=$1
  shift
  if "$@" >/tmp/check.out 2>&1; then pass "$what"; else
    fail "$what: $("$bb" tail -n 3 /tmp/check.out | "$bb" tr '\n' ' ')"
  fi
}
uptime() { "$bb" cut -d' ' -f1 /proc/uptime; }
finish() {
  echo "INFO guest time at the end: $(uptime)s"
  echo "GUEST DONE"
  "$bb" sync
  "$bb" poweroff -f
}
echo "INFO guest time at the checks' start (systemd up): $(uptime)s"

check "cylscan's arm64 package runs ($(uname -m), kernel $kver)" /usr/bin/cylscan --version
# The package's sysusers.d file, applied by systemd at boot as on a board.
groups=$("$bb" id -nG cylscan 2>/dev/null)
if echo " $groups " | "$bb" grep -q ' gpio ' && echo " $groups " | "$bb" grep -q ' video '; then
  pass "systemd-sysusers made the package's user: cylscan in groups $groups"
else
  fail "the package's user cylscan in groups gpio and video: id says '${groups:-no such user}'"
fi

# --- gpio-sim: one bank whose lines carry the board profile's names ---
modprobe configfs 2>/dev/null
"$bb" mount -t configfs configfs /sys/kernel/config 2>/dev/null
names=$("$bb" sed -n '/^\[gpio\]/,/^\[/p' "$board/board.toml" |
  "$bb" sed -n 's/^[a-z]* *= *{ *name *= *"\([^"]*\)".*/\1/p')
if ! "$bb" insmod /opt/emulated-board/modules/gpio-sim.ko; then
  fail "gpio-sim loads"
else
  pass "gpio-sim loads (built out of tree, irq_sim inside)"
  chip=/sys/kernel/config/gpio-sim/cylscan
  "$bb" mkdir -p "$chip/bank0"
  n=0
  for name in $names; do
    "$bb" mkdir -p "$chip/bank0/line$n"
    echo "$name" >"$chip/bank0/line$n/name"
    n=$((n + 1))
  done
  echo "$n" >"$chip/bank0/num_lines"
  echo 1 >"$chip/live"
  missing=""
  for name in $names; do
    gpioinfo "$name" >/dev/null 2>&1 || missing="$missing $name"
  done
  if [ -n "$names" ] && [ -z "$missing" ]; then
    pass "gpio-sim chip $("$bb" cat "$chip/bank0/chip_name") has the board's lines: $(echo $names)"
  else
    fail "gpio-sim lines by name: not found:${missing:- (no names in $board/board.toml)}"
  fi
fi

# --- vivid: capture + output nodes, output looped back to capture ---
if ! modprobe vivid n_devs=1 node_types=0x101 >/tmp/modprobe.out 2>&1; then
  fail "vivid loads: $("$bb" cat /tmp/modprobe.out)"
else
  pass "vivid loads (capture and output nodes)"
fi
cap=""
out=""
for d in /dev/video*; do
  info=$(v4l2-ctl -d "$d" --info 2>/dev/null)
  case "$info" in *"Driver name"*vivid*) ;; *) continue ;; esac
  # The node's own capabilities (after "Device Caps"), not the driver's.
  caps=$(echo "$info" | "$bb" sed -n '/Device Caps/,$p')
  case "$caps" in
  *"Video Capture"*) [ -z "$cap" ] && cap=$d ;;
  esac
  case "$caps" in
  *"Video Output"*) [ -z "$out" ] && out=$d ;;
  esac
done
echo "INFO vivid capture $cap, output $out (nodes: $(echo /dev/video*))"
camdev=$("$bb" sed -n 's/^device *= *"\(\/dev\/video[0-9]*\)".*/\1/p' "$board/board.toml" | "$bb" head -n1)
if [ -n "$cap" ] && [ "$cap" = "$camdev" ] && [ -n "$out" ]; then
  pass "the profile's camera $camdev is vivid's capture node; the feeder writes to its output $out"
else
  fail "the profile's camera '$camdev' is vivid's capture node: vivid gave capture '$cap', output '$out'"
fi
[ -n "$cap" ] || v4l2-ctl -d /dev/video1 --info 2>&1 | "$bb" head -n 5
formats=$(v4l2-ctl -d "$cap" --list-formats 2>/dev/null)
case "$formats" in
*"'GREY'"*) pass "vivid's capture offers GREY (the board profile's 8-bit format)" ;;
*) fail "vivid's capture offers GREY: it offers $(echo "$formats" | "$bb" grep -o "'[^']*'" | "$bb" tr '\n' ' ')" ;;
esac
# Loopback (6.12): HDMI input 3 on capture, output 1 on output, HDMI output 0 connected to it.
v4l2-ctl -d "$cap" -i 3 >/dev/null
v4l2-ctl -d "$out" -o 1 >/dev/null
v4l2-ctl -d "$out" -c hdmi_000_0_is_connected_to=2 >/dev/null 2>&1 ||
  v4l2-ctl -d "$cap" -c hdmi_000_0_is_connected_to=2 >/dev/null 2>&1
v4l2-ctl -d "$cap" -c osd_text_mode=2 >/dev/null 2>&1
w=$("$bb" sed -n 's/^width *= *\([0-9]*\).*/\1/p' "$board/board.toml" | "$bb" head -n1)
h=$("$bb" sed -n 's/^height *= *\([0-9]*\).*/\1/p' "$board/board.toml" | "$bb" head -n1)
v4l2-ctl -d "$out" --set-dv-bt-timings width=$w,height=$h >/dev/null 2>&1
v4l2-ctl -d "$cap" --set-dv-bt-timings width=$w,height=$h >/dev/null 2>&1
v4l2-ctl -d "$out" --set-fmt-video-out=width=$w,height=$h,pixelformat=GREY >/dev/null 2>&1
v4l2-ctl -d "$cap" --set-fmt-video=width=$w,height=$h,pixelformat=GREY >/dev/null 2>&1
echo "INFO capture $(v4l2-ctl -d "$cap" --get-fmt-video 2>/dev/null | "$bb" grep -E 'Width|Pixel' | "$bb" tr -s ' \n' ' ')"
echo "INFO output $(v4l2-ctl -d "$out" --get-fmt-video-out 2>/dev/null | "$bb" grep -E 'Width|Pixel' | "$bb" tr -s ' \n' ' ')"
"$bb" head -c $((w * h)) /dev/urandom >/tmp/pattern.raw
v4l2-ctl -d "$out" --stream-out-mmap --stream-from=/tmp/pattern.raw --stream-loop \
  --stream-count=100000 >/dev/null 2>&1 &
writer=$!
"$bb" sleep 2
v4l2-ctl -d "$cap" --stream-mmap --stream-skip=5 --stream-count=1 --stream-to=/tmp/captured.raw \
  >/tmp/capture.out 2>&1
"$bb" kill "$writer" 2>/dev/null
wait "$writer" 2>/dev/null
if "$bb" cmp -s /tmp/pattern.raw /tmp/captured.raw; then
  pass "vivid loops a frame written to $out back out of $cap bit-exactly (${w}x${h} GREY)"
else
  fail "vivid loopback: the captured frame differs from the written one ($("$bb" wc -c </tmp/captured.raw 2>/dev/null) bytes; $("$bb" tail -n 2 /tmp/capture.out | "$bb" tr '\n' ' '))"
fi

# The package's udev rules: the GPIO chip to group gpio, the cameras to video.
udevadm settle --timeout=60
gpiochip=/dev/$("$bb" cat /sys/kernel/config/gpio-sim/cylscan/bank0/chip_name 2>/dev/null)
owners="$gpiochip $("$bb" stat -c '%G %a' "$gpiochip" 2>&1), $cap $("$bb" stat -c '%G %a' "$cap" 2>&1)"
if [ "$("$bb" stat -c %G "$gpiochip" 2>/dev/null)" = gpio ] && [ "$("$bb" stat -c %G "$cap" 2>/dev/null)" = video ]; then
  pass "udev applied the package's rules: $owners"
else
  fail "udev and the package's rules: $owners (want group gpio and video)"
fi

echo "INFO guest time before the scans: $(uptime)s"
. /opt/emulated-board/guest-scan.sh
finish
