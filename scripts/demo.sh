#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The main job: install, build, calibrate the virtual head the way the paper
# calibrates a real one, then start the daemon cylscand on it with the
# calibration installed, so that http://127.0.0.1:8080 shows the head's page
# and can scan its default scene (the 50 mm reference sphere before a plane).
#
#   bash scripts/demo.sh            # serve until Ctrl-C
#   bash scripts/demo.sh --once     # one scan through the API, then stop
#   bash scripts/demo.sh --360      # the 360° head (board/sim360, four cameras
#                                   # at 320x256): every camera calibrated one
#                                   # direction at a time, the extrinsics on a
#                                   # turntable, the merged cloud in the page
#   bash scripts/demo.sh --on-head  # the head calibrates itself through the
#                                   # daemon's API (calibration session: 40
#                                   # board pairs, 14 plane poses, the solve,
#                                   # the install), then checks the sphere
#
# The calibration (simulate, calibrate-stereo, calibrate: a few minutes at the
# head's full 1000x800) is kept in out/demo (out/demo360) and reused by later runs.
set -euo pipefail
cd "$(dirname "$0")/.."
once=0
ring=0
on_head=0
while [ $# -gt 0 ]; do
  case "$1" in
    --once) once=1; shift ;;
    --360) ring=1; shift ;;
    --on-head) on_head=1; shift ;;
    *) break ;;
  esac
done
if [ "$ring" -eq 1 ]; then
  out=${1:-out/demo360}
elif [ "$on_head" -eq 1 ]; then
  out=${1:-out/demo-on-head}
else
  out=${1:-out/demo}
fi
listen=${CYLSCAN_LISTEN:-127.0.0.1:8080}

bash scripts/install-deps.sh
cmake --preset default >/dev/null
targets=(cylscan cylscand)
# The page is bundled from npm (target web) when npm is there.
if cmake --build --preset default --target help | grep -q '^web:'; then targets+=(web); fi
cmake --build --preset default -j "$(nproc)" --target "${targets[@]}"
bin=./build/default
cylscan=$bin/tools/cylscan
cylscand=$bin/firmware/daemon/cylscand
mkdir -p "$out"
data="$out/dataset"

board=board/sim
if [ "$ring" -eq 1 ]; then
  # The ring head's calibration is the test fixture's recipe (tests/fixtures/
  # ring_head.cmake: per direction simulate --camera NAME, calibrate-stereo,
  # calibrate; the turntable dataset), then the extrinsics from it.
  echo "== the 360° head: calibrate each camera, one direction at a time (a few minutes)"
  cmake -DCYLSCAN="$cylscan" -DSOURCE_DIR="$(pwd)" -DOUT="$out" -P tests/fixtures/ring_head.cmake
  if [ ! -f "$out/head.json" ] || [ "$out/head.json" -ot "$out/ready" ]; then
    echo "== calibrate-head: every camera's pose in the head frame, from the turntable scans"
    $cylscan calibrate-head --calib-dir "$out/calib" --out "$out/head.json" "$out"/turntable/turn*
  fi
  board="$out/board"
elif [ "$on_head" -eq 0 ] && [ ! -f "$out/calib.bin" ]; then
  echo "== simulate: the virtual head renders its calibration data (docs/formats.md, simulated dataset)"
  rm -rf "$data"
  $cylscan simulate --out "$data" --boards 40
  echo "== calibrate-stereo: the checkerboard pairs of the main and aux cameras"
  $cylscan calibrate-stereo --board "$data/board" --out "$out/stereo.yaml"
  echo "== calibrate: quasi-calibration from $(ls "$data/calib" | wc -l) plane poses"
  $cylscan calibrate --stereo "$out/stereo.yaml" --out "$out/calib.tmp" "$data"/calib/pose*
  mv "$out/calib.tmp" "$out/calib.bin"
  echo "== the paper's method offline: reconstruct a 50 mm sphere from the main camera alone"
  $cylscan reconstruct --calib "$out/calib.bin" --out "$out/sphere_1.ply" "$data/test/sphere_1"
  $cylscan evaluate sphere --radius 50 "$out/sphere_1.ply"
fi

echo "== cylscand on the virtual head ($board), data in $out/data"
log="$out/cylscand.log"
coproc DAEMON { exec "$cylscand" --board "$board" --listen "$listen" --data "$out/data" 2>"$log"; }
daemon_pid=$DAEMON_PID
trap 'kill -TERM "$daemon_pid" 2>/dev/null || true; wait "$daemon_pid" 2>/dev/null || true' EXIT
if ! read -r -t 30 line <&"${DAEMON[0]}"; then
  echo "cylscand did not start; its log ($log):" >&2
  cat "$log" >&2
  exit 1
fi
echo "$line"
url=${line#*listening on }
url=${url%% *}
if [ "$ring" -eq 1 ]; then
  for qcal in "$out"/calib/*.qcal; do
    camera=$(basename "$qcal" .qcal)
    echo "== install $camera's calibration: PUT $url/api/v1/calibration?camera=$camera"
    curl -sS --fail-with-body -X PUT --data-binary @"$qcal" \
      -H 'Content-Type: application/octet-stream' "$url/api/v1/calibration?camera=$camera" >/dev/null
  done
  echo "== install the extrinsics: PUT $url/api/v1/head"
  curl -sS --fail-with-body -X PUT --data-binary @"$out/head.json" \
    -H 'Content-Type: application/json' "$url/api/v1/head" >/dev/null
elif [ "$on_head" -eq 1 ]; then
  # POST BODY PATH: the answer, or the error and exit.
  post() { curl -sS --fail-with-body -X POST -H 'Content-Type: application/json' -d "$1" "$url$2"; }
  waitIdle() {
    until curl -sS "$url/api/v1/status" | grep -q '"state":"idle"'; do sleep 0.2; done
  }
  started=$SECONDS
  echo "== the head calibrates itself: POST $url/api/v1/calibration/session"
  post '{}' /api/v1/calibration/session >/dev/null
  for i in $(seq 0 39); do
    scene=$(printf 'calibration/board%02d.toml' "$i")
    answer=$(post "{\"scene\": \"$scene\"}" /api/v1/calibration/session/boards)
    echo "   board pair $i ($scene): $answer"
  done
  curl -sS "$url/api/v1/calibration/session" | sed -n 's/.*"advice":"\([^"]*\)".*/   guidance: \1/p'
  for i in $(seq 0 13); do
    scene=$(printf 'calibration/plane%02d.toml' "$i")
    post "{\"scene\": \"$scene\"}" /api/v1/calibration/session/planes >/dev/null
    waitIdle
    echo "   plane pose $i ($scene) taken"
  done
  echo "== the solve, on the head (stereo calibration, then quasi-calibration)"
  solve_start=$SECONDS
  post '{}' /api/v1/calibration/session/solve >/dev/null
  while curl -sS "$url/api/v1/calibration/session" | grep -q '"state":"solving"'; do sleep 1; done
  session=$(curl -sS "$url/api/v1/calibration/session")
  case "$session" in *'"state":"solved"'*) ;; *) echo "$session" >&2; exit 1 ;; esac
  echo "   solved in $((SECONDS - solve_start)) s; peak memory of the daemon:" \
    "$(sed -n 's/^VmHWM:[[:space:]]*//p' "/proc/$daemon_pid/status")"
  echo "$session" | grep -o '"stereo_rms_px":[^,]*\|"pooled_rmse_mm":[^,]*' | sed 's/^/   /'
  echo "== install: POST $url/api/v1/calibration/session/install"
  post '{}' /api/v1/calibration/session/install
  echo
  echo "== check the 50 mm sphere: POST $url/api/v1/checks"
  check=$(post '{"artifact": "sphere", "radius_mm": 50}' /api/v1/checks | sed -n 's/.*"id":"\([^"]*\)".*/\1/p')
  waitIdle
  curl -sS "$url/api/v1/checks" | grep -o "{[^{}]*\"id\":\"$check\"[^{}]*}"
  echo "   the head calibrated itself in $((SECONDS - started)) s"
else
  echo "== install the calibration: PUT $url/api/v1/calibration"
  curl -sS --fail-with-body -X PUT --data-binary @"$out/calib.bin" \
    -H 'Content-Type: application/octet-stream' "$url/api/v1/calibration"
  echo
fi

if [ "$once" -eq 1 ]; then
  echo "== one scan through the API"
  id=$(curl -sS --fail-with-body -X POST "$url/api/v1/scans" | sed -n 's/.*"id":"\([^"]*\)".*/\1/p')
  for _ in $(seq 1 600); do
    scan=$(curl -sS --fail-with-body "$url/api/v1/scans/$id")
    case "$scan" in
      *'"state":"done"'* | *'"state":"failed"'*) break ;;
    esac
    sleep 0.5
  done
  echo "$scan"
  case "$scan" in *'"state":"done"'*) ;; *) exit 1 ;; esac
  curl -sS --fail-with-body -o "$out/scan.ply" "$url/api/v1/scans/$id/cloud.ply"
  echo "demo: scan $id -> $out/scan.ply"
  exit 0
fi
echo "demo: open $url in a browser (Ctrl-C stops the daemon)"
wait "$daemon_pid"
