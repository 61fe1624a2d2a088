#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Prints, for each test that failed in the last CTest run of BUILD_DIR, the
# lines of its output that say why (failures, errors, problems, timeouts,
# and the two lines after each), ten at most per test. CI keeps only part
# of a long log, and the output CTest prints on failure sits far above a
# stage's last lines: this digest is printed just before them.
# Usage: scripts/failed-tests-digest.sh BUILD_DIR [LINES_PER_TEST]
set -uo pipefail
build=${1:?usage: failed-tests-digest.sh BUILD_DIR [LINES_PER_TEST]}
per_test=${2:-10}
failed_list=$build/Testing/Temporary/LastTestsFailed.log
log=$build/Testing/Temporary/LastTest.log
[ -s "$failed_list" ] && [ -f "$log" ] || exit 0
shown=0
while IFS=: read -r _ name; do
  [ -n "$name" ] || continue
  shown=$((shown + 1))
  # Only the first few failures: a broken build fails hundreds alike.
  if [ "$shown" -gt 4 ]; then
    echo "digest: $(($(wc -l < "$failed_list") - 4)) more failed test(s); see the log above"
    break
  fi
  echo "digest: $name failed; why, from its output:"
  output=$(awk -v name="$name" '
    $0 ~ "^[0-9]+/[0-9]+ Test: " && $3 == name { inside = 1; next }
    inside && /^<end of output>/ { exit }
    inside { print }
  ' "$log" | tail -n 60)
  # With the two lines after each: a failure often lists its reasons below.
  why=$(grep -aiE -A2 --no-group-separator 'fail|error|problem|timeout|timed out|expected|abort|assert|exception' <<< "$output")
  # No line says why: its last lines, then.
  [ -n "$why" ] || why=$output
  tail -n "$per_test" <<< "$why" | cut -c1-300 | sed 's/^/  | /'
done < "$failed_list"
