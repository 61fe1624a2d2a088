#!/usr/bin/env bash
# The test command: installs what the build needs, builds (Release, with
# tests and benchmarks), and runs the whole test suite through CTest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset default
cmake --build --preset default -j "$(nproc)"
ctest --preset default -j "$(nproc)"
