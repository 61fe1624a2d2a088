#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Sanitized test runs: scripts/sanitize.sh [asan|tsan|all] (default all).
#   asan  AddressSanitizer + UndefinedBehaviorSanitizer, the whole suite
#         except the package test (preset "asan", build/asan)
#   tsan  ThreadSanitizer, the tests that run threads: firmware, drivers,
#         daemon, http, daemon_e2e (preset "tsan", build/tsan)
# Configures, builds and runs each through its CMake presets; the test presets
# set ASAN/UBSAN/TSAN_OPTIONS so that a report in any process, the daemon and
# the CLI the tests start included, fails the test. Exits non-zero if any
# build or test fails. JOBS=N overrides the parallelism (default: nproc).
# The test fixtures' calibrations (rendering and fitting the quick heads,
# single-threaded, minutes under a sanitizer) are made by the Release build's
# cylscan when build/default is configured (CYLSCAN_FIXTURE_TOOL,
# tests/CMakeLists.txt); FIXTURE_TOOL=PATH names another, FIXTURE_TOOL=self
# makes them with the sanitized build's own. Every test still runs sanitized.
set -euo pipefail
cd "$(dirname "$0")/.."

which="${1:-all}"
case "$which" in
  asan) presets=(asan) ;;
  tsan) presets=(tsan) ;;
  all) presets=(asan tsan) ;;
  *)
    echo "usage: $0 [asan|tsan|all]" >&2
    exit 2
    ;;
esac
jobs="${JOBS:-$(nproc)}"
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi

fixture_tool="${FIXTURE_TOOL:-}"
if [ -z "$fixture_tool" ] && [ -f build/default/CMakeCache.txt ]; then
  echo "== the fixtures' calibrations: build/default's cylscan (Release)"
  if ! cmake --build build/default -j "$jobs" --target cylscan >/dev/null; then
    echo "sanitize.sh: building build/default's cylscan failed (FIXTURE_TOOL=self skips it)" >&2
    exit 2
  fi
  fixture_tool="$PWD/build/default/tools/cylscan"
fi
[ "$fixture_tool" != self ] || fixture_tool=""
if [ -n "$fixture_tool" ] && [ ! -x "$fixture_tool" ]; then
  echo "sanitize.sh: FIXTURE_TOOL=$fixture_tool is not an executable cylscan" >&2
  exit 2
fi

status=0
for preset in "${presets[@]}"; do
  echo "== $preset: configure and build (build/$preset)"
  start=$(date +%s)
  cmake --preset "$preset" "${launcher[@]}" -DCYLSCAN_FIXTURE_TOOL="$fixture_tool" >/dev/null
  if [ "$preset" = tsan ]; then
    # Only the programs the tsan test preset runs (its label filter), and
    # cylscan when it makes the fixture.
    targets=(firmware_tests drivers_tests daemon_tests http_tests daemon_e2e_tests cylscand)
    [ -n "$fixture_tool" ] || targets+=(cylscan)
    cmake --build --preset "$preset" -j "$jobs" --target "${targets[@]}"
  else
    cmake --build --preset "$preset" -j "$jobs"
  fi
  built=$(date +%s)
  echo "== $preset: test"
  # CTest prints its summary ("N% tests passed, ..." and the failed tests).
  if ! ctest --preset "$preset" -j "$jobs"; then
    status=1
    echo "== $preset: FAILED" >&2
  fi
  done_at=$(date +%s)
  echo "== $preset: build $((built - start)) s, tests $((done_at - built)) s"
done
exit "$status"
