# SPDX-License-Identifier: Apache-2.0
# Sourced by guest.sh: the scans. cylscand, the installed arm64 daemon,
# runs under the package's hardened systemd unit with the board profile
# /etc/cylscan/cylscan.toml names (board/qemu-virt): it drives the gpio-sim
# lines and captures vivid's capture node ($cap). The feeder plays the stage
# and the optics and queues the frames on vivid's output node ($out), which
# vivid loops back to the capture. Scans are asked for over the HTTP API.
em=/opt/emulated-board
feeder=$em/cylscan-emulated-feeder
chipdir=/sys/kernel/config/gpio-sim/cylscan
api=http://127.0.0.1:8080/api/v1
data=/var/lib/cylscan
frames=5
"$bb" mount -t debugfs debugfs /sys/kernel/debug 2>/dev/null
"$bb" mount -t tracefs tracefs /sys/kernel/tracing 2>/dev/null

# One feeder run: start_feeder LOG [feeder options]; stop_feeder.
start_feeder() {
  flog=$1
  shift
  "$bb" rm -f "$flog" "$flog.ready"
  "$feeder" run --head "$em/reference-board/head.toml" --scene "$em/reference-board/scene.toml" \
    --chip "$chipdir" --video "$out" --log "$flog" --rt-priority 90 "$@" 2>>"$res/feeder.err" &
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
# A scalar of a compact JSON object: json KEY < TEXT.
json() { "$bb" sed -n "s/.*\"$1\":\"\{0,1\}\([^\",}]*\).*/\1/p" | "$bb" head -n1; }
# curl: busybox-static's wget crashes in its static resolver.
get() { curl -sS -f -m 30 "$api/$1"; }
# post_scan OPTIONS: the new scan's id.
post_scan() {
  curl -sS -f -m 30 -H 'Content-Type: application/json' --data "$1" "$api/scans" | json id
}
# await_scan ID SECONDS: its final scan object (done or failed) in $res/scan-ID.json.
await_scan() {
  i=0
  while [ "$i" -lt "$2" ]; do
    get "scans/$1" >"$res/scan-$1.json" 2>/dev/null
    case "$(json state <"$res/scan-$1.json")" in done | failed) return 0 ;; esac
    "$bb" sleep 2
    i=$((i + 2))
  done
  return 1
}
unit_logs() { journalctl -u cylscand --no-pager -n 5 -o cat 2>&1 | "$bb" tr '\n' ' '; }

# The in-process twin (the same profile, stage and scan on the virtual head)
# was scanned on the host by the same arm64 program under qemu-user (run.sh):
# its frames are in $res/ref, its phase in $res/ref-phase.
[ -f "$res/ref-phase/absolute.tiff" ] || fail "the in-process reference scan's phase is there (run.sh)"

# --- cylscand under the package's unit --------------------------------------
if ! systemctl start cylscand >"$res/start.out" 2>&1; then
  fail "systemctl start cylscand: $("$bb" cat "$res/start.out") $(unit_logs)"
else
  pass "cylscand started under its unit (Type=notify: READY once the board was open and it listened)"
fi
pid=$(systemctl show -p MainPID --value cylscand)
st=/proc/$pid/status
gid_of() { "$bb" sed -n "s/^$1:[^:]*:\([0-9]*\):.*/\1/p" /etc/group; }
uid=$("$bb" awk '/^Uid:/ { print $2 }' "$st" 2>/dev/null)
gids=" $("$bb" awk '/^Groups:/ { $1 = ""; print }' "$st" 2>/dev/null) "
capeff=$("$bb" awk '/^CapEff:/ { print $2 }' "$st" 2>/dev/null)
nnp=$("$bb" awk '/^NoNewPrivs:/ { print $2 }' "$st" 2>/dev/null)
seccomp=$("$bb" awk '/^Seccomp:/ { print $2 }' "$st" 2>/dev/null)
user=$("$bb" awk -F: -v u="$uid" '$3 == u { print $1 }' /etc/passwd)
hardening="user $user, groups$gids, CapEff $capeff, NoNewPrivs $nnp, Seccomp $seccomp"
# CAP_SYS_NICE is capability 23: 0x800000, and nothing else.
case "$gids" in
*" $(gid_of gpio) "*) in_gpio=1 ;;
*) in_gpio=0 ;;
esac
case "$gids" in
*" $(gid_of video) "*) in_video=1 ;;
*) in_video=0 ;;
esac
if [ "$user" = cylscan ] && [ "$in_gpio$in_video" = 11 ] && [ "$capeff" = 0000000000800000 ] &&
  [ "$nnp" = 1 ] && [ "$seccomp" = 2 ]; then
  pass "cylscand runs with the unit's hardening: $hardening"
else
  fail "cylscand's hardening (want user cylscan in gpio and video, CapEff 0000000000800000, NoNewPrivs 1, Seccomp 2): $hardening"
fi
i=0
until get status >"$res/status.json" 2>"$res/status.err" || [ "$i" -ge 60 ]; do
  "$bb" sleep 1
  i=$((i + 1))
done
if [ -s "$res/status.json" ]; then
  pass "cylscand answers on its API: $("$bb" head -c 200 "$res/status.json")"
else
  fail "cylscand answers on its API: $("$bb" cat "$res/status.err")"
fi

# The daemon's memory without the virtual head in its process (kB): what a
# small board must hold. VmHWM is the peak so far, VmRSS what it holds now.
daemon_pid() { systemctl show -p MainPID --value cylscand 2>/dev/null; }
rss() {
  "$bb" sed -n -e 's/^VmHWM:[[:space:]]*\([0-9]*\) kB/VmHWM \1 kB/p' \
    -e 's/^VmRSS:[[:space:]]*\([0-9]*\) kB/VmRSS \1 kB/p' "/proc/$(daemon_pid)/status" 2>/dev/null |
    "$bb" tr '\n' ' '
}
# Where it is: the five largest mappings by resident set (kB; "anon" sums
# the large allocations, the threads' arenas and their stacks).
largest_mappings() {
  "$bb" awk '/^[0-9a-f]+-[0-9a-f]+ / { name = ($6 == "") ? "anon" : $6 }
    /^Rss:/ { rss[name] += $2 }
    END { for (n in rss) print rss[n], n }' "/proc/$(daemon_pid)/smaps" 2>/dev/null |
    "$bb" sort -rn | "$bb" head -n 5 | "$bb" tr '\n' ';'
}
echo "INFO cylscand idle: $(rss); largest: $(largest_mappings)"

# --- a calibration for vivid's image size -----------------------------------
# The device's budget is a full scan with reconstruction in 150 MB. There is
# no head geometry to calibrate here, so the feeder makes a calibration from
# the in-process twin's phase (the same scan's): every pixel valid, within
# its phase range, on a plane. The daemon then reconstructs every pixel with
# a phase, as a calibrated head's would, and the memory it takes is the
# device's. The scan's other checks do not depend on it.
calibrated=0
if ! "$feeder" calibration "$res/ref-phase" --out "$res/synthetic.qcal" >"$res/qcal.out" 2>&1; then
  fail "the feeder's calibration for vivid's image size: $("$bb" cat "$res/qcal.out")"
else
  code=$(curl -sS -m 60 -o "$res/put-calibration.json" -w '%{http_code}' -X PUT \
    -H 'Content-Type: application/octet-stream' --data-binary "@$res/synthetic.qcal" "$api/calibration")
  if [ "$code" = 200 ]; then
    calibrated=1
    echo "INFO calibration installed ($("$bb" cat "$res/qcal.out")); cylscand: $(rss)"
  else
    fail "PUT /api/v1/calibration ($("$bb" cat "$res/qcal.out")): $code $("$bb" head -c 300 "$res/put-calibration.json")"
  fi
fi

# --- a full scan through the kernel's drivers ---------------------------------
if ! start_feeder "$res/feeder-scan.log"; then
  fail "the feeder starts: $("$bb" tail -n 3 "$res/feeder.err" | "$bb" tr '\n' ' ')"
else
  t=$("$bb" date +%s)
  id=$(post_scan "{\"frames\":$frames,\"save_bundle\":true}")
  state=none
  if [ -n "$id" ] && await_scan "$id" 600; then state=$(json state <"$res/scan-$id.json"); fi
  took=$(($("$bb" date +%s) - t))
  stop_feeder
  echo "INFO feeder: $(summary "$res/feeder-scan.log")"
  scan=$res/scan-$id.json
  bundle=$data/scans/$id/bundle
  if [ "$state" = done ] && [ -f "$bundle/capture.json" ]; then
    pass "a full scan through cylscand's API finishes (scan $id, $frames frames per set, ${took}s, $(json board_seconds <"$scan") s of board time), its bundle stored"
  else
    fail "a full scan through cylscand's API (scan '${id:-none}', state $state): $("$bb" head -c 400 "$scan" 2>/dev/null) $(unit_logs)"
  fi
  echo "INFO cylscand after the scan: $(rss); largest: $(largest_mappings); the scan's peak resident set $(json peak_resident_bytes <"$scan") bytes"
  if [ "$calibrated" = 1 ]; then
    points=$(json points <"$scan")
    if [ "$state" = done ] && [ "$(json calibrated <"$scan")" = true ] && [ "${points:-0}" -gt 0 ]; then
      pass "the scan reconstructed a cloud with the installed calibration: $points points"
    else
      fail "the scan's reconstruction: state $state, calibrated '$(json calibrated <"$scan")', points '${points:-none}'"
    fi
    # The device's budget for a full scan with reconstruction: 150 MB (10^6
    # bytes; VmHWM is in KiB), the daemon's peak since it started.
    hwm=$("$bb" sed -n 's/^VmHWM:[[:space:]]*\([0-9]*\) kB/\1/p' "/proc/$(daemon_pid)/status" 2>/dev/null)
    mb=$("$bb" awk -v k="${hwm:-0}" 'BEGIN { printf "%.1f", k * 1024 / 1e6 }')
    if [ -n "$hwm" ] && [ $((hwm * 1024)) -le 150000000 ]; then
      pass "cylscand's peak resident set through a scan with reconstruction is within the device's 150 MB: $mb MB"
    else
      fail "cylscand's peak resident set through a scan with reconstruction: $mb MB, over the device's 150 MB"
    fi
  fi
  echo "INFO the scan's step executor: $("$bb" sed -n 's/.*"step_jitter":\({[^}]*}\).*/\1/p' "$scan"), re-ramps $(json step_reramps <"$scan")"
  if [ "$(json realtime <"$scan")" = true ]; then
    pass "the scan's step thread ran SCHED_FIFO (the unit's ambient CAP_SYS_NICE)"
  else
    fail "the scan's step thread ran SCHED_FIFO: realtime '$(json realtime <"$scan")'; warnings: $("$bb" sed -n 's/.*"warnings":\(\[[^]]*\]\).*/\1/p' "$scan")"
  fi
  # Homing: the firmware found home through an edge event of the gpio-sim
  # line the feeder pulled (the scan's first motion), and met it again for the
  # step check (passing it, or seeking it after the scan).
  edges=$(field "$res/feeder-scan.log" home_edges)
  if [ "$state" = done ] && [ "$(json homed <"$scan")" = true ] && [ "${edges:-0}" -ge 2 ]; then
    pass "homing through real edge events of the home line ($edges edges pulled by the feeder, the step check included)"
  else
    fail "homing through the home line's edges: scan $state, homed '$(json homed <"$scan")', $edges edges pulled"
  fi
  # vivid shows a queued frame from its next output tick and stamps capture
  # frames at their end: a frame stamped the image latency after its trigger
  # holds it if the feeder queued it two 60 Hz periods (34 ms) before that.
  latency=$("$bb" sed -n 's/^image_latency_ms *= *\([0-9.]*\).*/\1/p' "$board/board.toml")
  worst=$(field "$res/feeder-scan.log" worst_queue_ms)
  written=$(field "$res/feeder-scan.log" written)
  if [ "${written:-0}" -ge $((2 * frames)) ] &&
    "$bb" awk -v w="$worst" -v l="$latency" 'BEGIN { exit !(w + 34 <= l) }'; then
    pass "every frame ($written) was queued on vivid's output within $worst ms of its trigger edge (the profile's image latency: $latency ms)"
  else
    fail "the feeder's frames: ${written:-0} queued (want $((2 * frames))), the slowest ${worst:-?} ms after its trigger (the profile's image latency: $latency ms, less 34 ms)"
  fi
  pulses=$(field "$res/feeder-scan.log" pulses)
  lost=$(field "$res/feeder-scan.log" lost)
  overruns=$(field "$res/feeder-scan.log" trace_overruns)
  if [ "${pulses:-0}" -gt 0 ] && [ "$lost" = 0 ] && [ "$overruns" = 0 ] &&
    [ "$(field "$res/feeder-scan.log" enabled)" = 0 ]; then
    pass "the feeder followed every step pulse ($pulses, no trace overruns) and the stage ended disabled"
  else
    fail "the feeder's view of the stage: $pulses pulses, lost $lost, trace overruns $overruns, enabled $(field "$res/feeder-scan.log" enabled)"
  fi
  if [ "$state" = done ]; then
    spd=$("$bb" awk '/^full_steps_per_rev/{f=$3} /^microsteps/{m=$3} /^gear_ratio/{g=$3} END{print f*m*g/360}' "$board/board.toml")
    tol=$("$bb" sed -n 's/^step_check_tolerance_steps *= *\([0-9]*\).*/\1/p' "$board/board.toml")
    if "$feeder" angles "$bundle" "$res/feeder-scan.log" --steps-per-deg "$spd" --tolerance-steps "$tol" >"$res/angles.out" 2>&1; then
      pass "the bundle's executed angles are the steps the feeder counted: $("$bb" cat "$res/angles.out")"
    else
      fail "the bundle's executed angles against the feeder's count: $("$bb" cat "$res/angles.out")"
    fi
    # The frames themselves: what the firmware captured through the kernel
    # against what the in-process virtual head delivered for the same scan.
    same=0
    total=0
    for f in "$res"/ref/main/high/*.png "$res"/ref/main/low/*.png; do
      total=$((total + 1))
      "$bb" cmp -s "$f" "$bundle/main/${f#"$res"/ref/main/}" && same=$((same + 1))
    done
    if [ "$total" -gt 0 ] && [ "$same" -eq "$total" ]; then
      echo "INFO the $total captured frames are the in-process scan's, byte for byte"
    else
      # Not a failure by itself: a home edge seen a step late shifts every
      # angle by 0.025°, which the angle and phase checks bound.
      echo "INFO the captured frames against the in-process scan's: $same of $total identical"
    fi
    # The phase: the same as the in-process scan. Bound: one step (0.025° =
    # 31 mrad of the 5° period), should the firmware's zero lag the feeder's
    # home edge by a step; frames are 8 bit on both paths (GREY through vivid,
    # the virtual head's 8-bit camera) with the same noise: no further margin.
    if cylscan phase --out "$res/emu-phase" "$bundle" >"$res/phase.out" 2>&1 &&
      "$feeder" compare "$res/emu-phase" "$res/ref-phase" --max-rms 0.035 --max-mismatch 0.005 >"$res/compare.out" 2>&1; then
      pass "the reconstructed phase matches the in-process scan's: $("$bb" cat "$res/compare.out")"
    else
      fail "the reconstructed phase against the in-process scan's: $("$bb" cat "$res/phase.out" "$res/compare.out" | "$bb" tail -n 3 | "$bb" tr '\n' ' ')"
    fi
  fi
fi

# --- the camera stops: a capture timeout --------------------------------------
# The feeder queues two frames, then the camera's link goes silent (vivid
# drops every capture buffer): the daemon's scan fails, saying which frame.
# A new feeder is a new stage, at its start 2° above home, not where the last
# scan left it: the daemon starts again and homes, as a head does after power-up
# (kept running, it would rightly fail the scan for lost steps at home).
if ! systemctl restart cylscand >"$res/restart.out" 2>&1; then
  fail "systemctl restart cylscand: $("$bb" cat "$res/restart.out") $(unit_logs)"
fi
if ! start_feeder "$res/feeder-stop.log" --stop-after 2; then
  fail "the feeder starts (capture timeout)"
else
  id=$(post_scan "{\"frames\":$frames}")
  state=none
  if [ -n "$id" ] && await_scan "$id" 600; then state=$(json state <"$res/scan-$id.json"); fi
  "$bb" sleep 1
  stop_feeder
  echo "INFO feeder: $(summary "$res/feeder-stop.log")"
  reason=$(json error <"$res/scan-$id.json")
  get status >"$res/status-after.json" 2>/dev/null
  case "$reason" in
  *"no frame"*) timed_out=1 ;;
  *) timed_out=0 ;;
  esac
  if [ "$state" = failed ] && [ "$timed_out" = 1 ] && [ "$(json state <"$res/status-after.json")" = error ] &&
    [ "$(field "$res/feeder-stop.log" enabled)" = 0 ]; then
    pass "a capture timeout when the camera stops fails the scan with its reason, the daemon in state error and the stage disabled: $reason"
  else
    fail "the capture timeout: scan '${id:-none}' $state, reason '${reason:-none}', daemon state '$(json state <"$res/status-after.json")', stage enabled $(field "$res/feeder-stop.log" enabled)"
  fi
fi

# --- the unit stops ---------------------------------------------------------
systemctl stop cylscand
result=$(systemctl show -p Result --value cylscand)
if [ "$(systemctl is-active cylscand)" = inactive ] && [ "$result" = success ]; then
  pass "systemctl stop cylscand: the daemon exited cleanly (Result=$result)"
else
  fail "systemctl stop cylscand: $(systemctl is-active cylscand), Result=$result $(unit_logs)"
fi
