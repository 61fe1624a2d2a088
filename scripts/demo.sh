#!/usr/bin/env bash
# The main job: install, build, render a scan on the virtual head and turn it
# into absolute phase with the device's fixed-point engine.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset default >/dev/null
cmake --build --preset default -j "$(nproc)" --target cylscan
out=${1:-out/demo}
rm -rf "$out"
./build/default/tools/cylscan simulate --out "$out/dataset"
scene=$(ls "$out/dataset/test" | head -n 1)
./build/default/tools/cylscan phase --out "$out/phase" "$out/dataset/test/$scene"
echo "demo: phase maps of test scene '$scene' in $out/phase"
