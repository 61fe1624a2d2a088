# Sourced by guest.sh: the scans. The firmware (cylscan scan, the installed
# arm64 program) drives the gpio-sim lines and captures /dev/video0
# (v4l2loopback); the feeder plays the stage and the optics.
em=/opt/emulated-board
feeder=$em/cylscan-emulated-feeder
chipdir=/sys/kernel/config/gpio-sim/cylscan
frames=5
"$bb" mount -t debugfs debugfs /sys/kernel/debug 2>/dev/null
"$bb" mount -t tracefs tracefs /sys/kernel/tracing 2>/dev/null

# One feeder run: start_feeder LOG [feeder options]; stop_feeder.
start_feeder() {
  flog=$1
  shift
  "$bb" rm -f "$flog" "$flog.ready"
  "$feeder" run --head "$em/reference-board/head.toml" --scene "$em/reference-board/scene.toml" \
    --chip "$chipdir" --video /dev/video0 --log "$flog" --rt-priority 90 "$@" 2>>/tmp/feeder.err &
  fpid=$!
  i=0
  while [ ! -f "$flog.ready" ] && [ "$i" -lt 600 ] && "$bb" kill -0 "$fpid" 2>/dev/null; do
    "$bb" sleep 0.5
    i=$((i + 1))
  done
  [ -f "$flog.ready" ]
}
stop_feeder() {
  "$bb" kill -TERM "$fpid" 2>/dev/null
  wait "$fpid" 2>/dev/null
}
summary() { "$bb" grep '^pulses ' "$1"; }
field() { summary "$1" | "$bb" tr ' ' '\n' | "$bb" grep -A1 -x "$2" | "$bb" tail -n1; }

# The in-process twin (the same profile, stage and scan on the virtual head)
# was scanned on the host by the same arm64 program under qemu-user (run.sh):
# its phase is in /tmp/ref-phase.
[ -f /tmp/ref-phase/absolute.tiff ] || fail "the in-process reference scan's phase is there (run.sh)"

# --- a full scan through the kernel's drivers ---
if ! start_feeder /tmp/feeder-scan.log; then
  fail "the feeder starts: $("$bb" tail -n 3 /tmp/feeder.err | "$bb" tr '\n' ' ')"
else
  t=$("$bb" date +%s)
  cylscan scan --board "$board" --frames $frames --out /tmp/emu >/tmp/emu.out 2>&1
  rc=$?
  took=$(($("$bb" date +%s) - t))
  stop_feeder
  echo "INFO feeder: $(summary /tmp/feeder-scan.log)"
  if [ "$rc" -eq 0 ]; then
    pass "a full scan on the qemu-virt profile finishes ($frames frames per set, ${took}s): $("$bb" grep '^scan' /tmp/emu.out)"
  else
    fail "a full scan on the qemu-virt profile (exit $rc): $("$bb" tail -n 3 /tmp/emu.out | "$bb" tr '\n' ' ')"
  fi
  # Homing: the firmware found home through an edge event of the gpio-sim
  # line the feeder pulled (the scan's first motion), and re-found it after.
  edges=$(field /tmp/feeder-scan.log home_edges)
  if [ "$rc" -eq 0 ] && [ "${edges:-0}" -ge 2 ]; then
    pass "homing through real edge events of the home line ($edges edges pulled by the feeder, verify re-seek included)"
  else
    fail "homing through the home line's edges: scan exit $rc, $edges edges pulled"
  fi
  lost=$(field /tmp/feeder-scan.log lost)
  overruns=$(field /tmp/feeder-scan.log trace_overruns)
  if [ "$lost" = 0 ] && [ "$overruns" = 0 ] && [ "$(field /tmp/feeder-scan.log enabled)" = 0 ]; then
    pass "the feeder followed every step pulse (no trace overruns) and the stage ended disabled"
  else
    fail "the feeder's view of the stage: lost $lost, trace overruns $overruns, enabled $(field /tmp/feeder-scan.log enabled)"
  fi
  if [ "$rc" -eq 0 ]; then
    spd=$("$bb" awk '/^full_steps_per_rev/{f=$3} /^microsteps/{m=$3} /^gear_ratio/{g=$3} END{print f*m*g/360}' "$board/board.toml")
    tol=$("$bb" sed -n 's/^step_check_tolerance_steps *= *\([0-9]*\).*/\1/p' "$board/board.toml")
    if "$feeder" angles /tmp/emu /tmp/feeder-scan.log --steps-per-deg "$spd" --tolerance-steps "$tol" >/tmp/angles.out 2>&1; then
      pass "the bundle's executed angles are the steps the feeder counted: $("$bb" cat /tmp/angles.out)"
    else
      fail "the bundle's executed angles against the feeder's count: $("$bb" cat /tmp/angles.out)"
    fi
    # The frames themselves: what the firmware captured through the kernel
    # against what the in-process virtual head delivered for the same scan.
    same=0
    total=0
    for f in /tmp/ref/main/high/*.png /tmp/ref/main/low/*.png; do
      total=$((total + 1))
      "$bb" cmp -s "$f" "/tmp/emu/main/${f#/tmp/ref/main/}" && same=$((same + 1))
    done
    if [ "$total" -gt 0 ] && [ "$same" -eq "$total" ]; then
      echo "INFO the $total captured frames are the in-process scan's, byte for byte"
    else
      # Not a failure by itself: a home edge seen a step late shifts every
      # angle by 0.004°, which the angle and phase checks bound.
      echo "INFO the captured frames against the in-process scan's: $same of $total identical"
    fi
    # The phase: the same as the in-process scan. Bounds: the firmware's zero
    # may lag the feeder's home edge by up to the profile's step tolerance (2
    # steps = 0.008° = 10 mrad of the 5° period); 20 mrad RMS allows that
    # twice. Frames are 8 bit on both paths (GREY through v4l2loopback, the
    # virtual head's 8-bit camera), with the same noise: no further margin.
    if cylscan phase --out /tmp/emu-phase /tmp/emu >/tmp/phase.out 2>&1 &&
      "$feeder" compare /tmp/emu-phase /tmp/ref-phase --max-rms 0.02 --max-mismatch 0.005 >/tmp/compare.out 2>&1; then
      pass "the reconstructed phase matches the in-process scan's: $("$bb" cat /tmp/compare.out)"
    else
      fail "the reconstructed phase against the in-process scan's: $("$bb" cat /tmp/phase.out /tmp/compare.out | "$bb" tail -n 3 | "$bb" tr '\n' ' ')"
    fi
  fi
fi

# --- the camera stops: a capture timeout ---
# The same profile with the high set just above home (a short scan); the
# feeder writes two frames, then none.
"$bb" mkdir -p /tmp/stopboard
"$bb" sed -e 's/^high_start_deg = .*/high_start_deg = 3.0/' "$board/board.toml" >/tmp/stopboard/board.toml
if ! start_feeder /tmp/feeder-stop.log --stop-after 2; then
  fail "the feeder starts (capture timeout)"
else
  cylscan scan --board /tmp/stopboard --frames $frames --no-verify --out /tmp/stop >/tmp/stop.out 2>&1
  rc=$?
  "$bb" sleep 1
  stop_feeder
  echo "INFO feeder: $(summary /tmp/feeder-stop.log)"
  reason=$("$bb" grep -m1 'no frame' /tmp/stop.out)
  if [ "$rc" -ne 0 ] && [ -n "$reason" ] && [ "$(field /tmp/feeder-stop.log enabled)" = 0 ]; then
    pass "a capture timeout when the camera stops fails the scan (exit $rc) with its reason and the stage disabled: $reason"
  else
    fail "the capture timeout: exit $rc, reason '${reason:-none}', stage enabled $(field /tmp/feeder-stop.log enabled): $("$bb" tail -n 2 /tmp/stop.out | "$bb" tr '\n' ' ')"
  fi
fi
