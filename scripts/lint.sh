#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Static analysis: cppcheck and clang-tidy over the project's own sources
# (common, algo, formats, drivers, firmware, tools), with the compile commands of the
# default build (configured here if missing). Checks: .clang-tidy; cppcheck's
# suppressions with their reasons: scripts/cppcheck-suppressions.txt.
# Exits non-zero on any finding of either tool. JOBS=N sets the parallelism
# (default: nproc); scripts/lint.sh cppcheck|clang-tidy runs only one of them.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build="${LINT_BUILD_DIR:-build/default}"
jobs="${JOBS:-$(nproc)}"
which="${1:-all}"
dirs=(common algo formats drivers firmware tools)

if [ ! -f "$build/compile_commands.json" ]; then
  cmake --preset default >/dev/null
fi

# The project's translation units in the compile database, third-party and
# build/ excluded, as a compile database of their own (for cppcheck --project).
pattern="^${root}/($(IFS='|'; echo "${dirs[*]}"))/"
mkdir -p "$build/lint"
mapfile -t units < <(python3 - "$build/compile_commands.json" "$pattern" "$build/lint/compile_commands.json" <<'PY'
import json, re, sys
seen, kept = set(), []
for entry in json.load(open(sys.argv[1])):
    f = entry["file"]
    if re.match(sys.argv[2], f) and f not in seen:
        seen.add(f)
        kept.append(entry)
        print(f)
json.dump(kept, open(sys.argv[3], "w"), indent=1)
PY
)
if [ "${#units[@]}" -eq 0 ]; then
  echo "lint: no translation units of ${dirs[*]} in $build/compile_commands.json" >&2
  exit 2
fi

status=0
if [ "$which" = all ] || [ "$which" = cppcheck ]; then
  echo "== cppcheck (${#units[@]} files)"
  start=$(date +%s)
  mkdir -p "$build/cppcheck"
  # --project gives each file its own defines and include paths; system
  # headers (OpenCV, Eigen, ...) are not analysed (missingIncludeSystem).
  if ! cppcheck --project="$build/lint/compile_commands.json" \
    --enable=warning,style,performance,portability --std=c++20 --language=c++ \
    --inline-suppr --suppressions-list=scripts/cppcheck-suppressions.txt \
    --cppcheck-build-dir="$build/cppcheck" -j "$jobs" --quiet \
    --error-exitcode=1 --template='{file}:{line}: {severity} ({id}): {message}'; then
    status=1
    echo "== cppcheck: findings above" >&2
  fi
  echo "== cppcheck: $(($(date +%s) - start)) s"
fi

if [ "$which" = all ] || [ "$which" = clang-tidy ]; then
  echo "== clang-tidy (${#units[@]} files, -j$jobs)"
  start=$(date +%s)
  log=$(mktemp)
  # One process per file, jobs at a time; --quiet drops the per-file banner.
  # A finding is a "file:line:col: warning|error:" line.
  printf '%s\n' "${units[@]}" |
    xargs -P "$jobs" -n 1 clang-tidy -p "$build" --quiet >"$log" 2>/dev/null || true
  if grep -Eq '^[^ ]+:[0-9]+:[0-9]+: (warning|error):' "$log"; then
    grep -EA3 '^[^ ]+:[0-9]+:[0-9]+: (warning|error):' "$log" || true
    echo "== clang-tidy: $(grep -Ec '^[^ ]+:[0-9]+:[0-9]+: (warning|error):' "$log") findings" >&2
    status=1
  fi
  rm -f "$log"
  echo "== clang-tidy: $(($(date +%s) - start)) s"
fi
exit "$status"
