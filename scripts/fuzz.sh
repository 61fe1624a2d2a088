#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Bounded fuzzing of every parser of outside input: scripts/fuzz.sh [SECONDS] [TARGET...]
# Builds the libFuzzer targets of fuzz/ with clang (ASan + UBSan, build/fuzz),
# then runs each (default: all) for SECONDS (default 20) over a copy of its
# seed corpus fuzz/corpus/NAME, with its dictionary. A crash, leak, timeout
# (10 s for one input), UB report or out-of-memory (2 GB) fails the target;
# its input is kept in build/fuzz/artifacts/NAME/ and the log's last lines
# are printed. Prints one line per target and "N passed, N failed"; exits
# non-zero if any failed. JOBS=N sets the build's parallelism (default nproc),
# FUZZ_PARALLEL how many targets run at once (default JOBS), FUZZ_BUILD_DIR
# the build directory.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"

seconds="${1:-20}"
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [ "$seconds" -lt 1 ]; then
  echo "usage: $0 [SECONDS] [TARGET...]   (SECONDS: a whole number > 0)" >&2
  exit 2
fi
shift || true
all_targets=(http_router http_auth http_static daemon_toml board_toml capture_json png_frame
             stereo_yaml quasi_calibration calibration_upload scan_options)
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then targets=("${all_targets[@]}"); fi

declare -A dict=(
  [http_router]=http.dict [http_static]=http.dict
  [capture_json]=json.dict [scan_options]=json.dict
  [daemon_toml]=toml.dict [board_toml]=toml.dict
)

build="${FUZZ_BUILD_DIR:-$root/build/fuzz}"
jobs="${JOBS:-$(nproc)}"
for cc in clang clang++; do
  command -v "$cc" >/dev/null || { echo "fuzz: $cc not found (scripts/install-deps.sh)" >&2; exit 2; }
done
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi

start=$(date +%s)
echo "== fuzz: configure and build ($build)"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ "${launcher[@]}" \
  -DCYLSCAN_BUILD_FUZZ=ON -DCYLSCAN_BUILD_TESTS=OFF -DCYLSCAN_BUILD_BENCH=OFF \
  -DCYLSCAN_BUILD_WEB=OFF >/dev/null
build_targets=()
for t in "${targets[@]}"; do build_targets+=("fuzz_$t"); done
cmake --build "$build" -j "$jobs" --target "${build_targets[@]}"
built=$(date +%s)

scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
# One target: its result line in $scratch/$t.result, its status in $scratch/$t.rc.
run_target() {
  local t=$1
  local exe="$build/fuzz/fuzz_$t"
  local seeds="$root/fuzz/corpus/$t"
  local work="$scratch/$t"
  local artifacts="$build/artifacts/$t"
  mkdir -p "$work/corpus" "$work/tmp" "$artifacts"
  cp "$seeds"/* "$work/corpus/"
  local args=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
              -artifact_prefix="$artifacts/")
  if [ -n "${dict[$t]:-}" ]; then args+=(-dict="$root/fuzz/${dict[$t]}"); fi
  local t0 t1 rc=0
  t0=$(date +%s)
  TMPDIR="$work/tmp" "$exe" "${args[@]}" "$work/corpus" >"$work/log" 2>&1 || rc=$?
  t1=$(date +%s)
  local runs stats corpus
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/log" | tail -1 || true)
  stats=$(grep -E '^#[0-9]+' "$work/log" | grep -o 'cov: [0-9]* ft: [0-9]* corp: [0-9]*' |
    tail -1 || true)
  corpus=$(find "$work/corpus" -type f | wc -l)
  if [ "$rc" -eq 0 ]; then
    printf 'fuzz_%-20s passed  %6ss  %10s runs  %s  (corpus %s files)\n' \
      "$t" "$((t1 - t0))" "${runs:-?}" "${stats:-cov: ?}" "$corpus" >"$scratch/$t.result"
  else
    {
      printf 'fuzz_%-20s FAILED  %6ss  exit %s; input kept in %s\n' "$t" "$((t1 - t0))" "$rc" \
        "$artifacts/"
      grep -E 'ERROR|SUMMARY|runtime error|Test unit written|terminate|what\(\)' "$work/log" |
        head -12 | sed 's/^/    /' || true
    } >"$scratch/$t.result"
    cp "$work/log" "$artifacts/last.log"
  fi
  echo "$rc" >"$scratch/$t.rc"
}

# The targets run FUZZ_PARALLEL at a time (default: the build's jobs), each
# single-threaded, so a 2-core machine runs two at once.
parallel="${FUZZ_PARALLEL:-$jobs}"
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$parallel" ]; do wait -n || true; done
  run_target "$t" &
done
wait
passed=0
failed=0
for t in "${targets[@]}"; do
  cat "$scratch/$t.result" 2>/dev/null || echo "fuzz_$t: no result (the runner itself failed)"
  if [ "$(cat "$scratch/$t.rc" 2>/dev/null || echo 1)" = 0 ]; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
  fi
done
end=$(date +%s)
echo "fuzz: build $((built - start)) s, runs $((end - built)) s"
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
