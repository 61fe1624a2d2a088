#!/bin/sh
# SPDX-License-Identifier: Apache-2.0
# The in-process twin of the emulated board: board/qemu-virt's profile (the
# same stage, motion and scan) with its camera on the virtual head of
# tests/emulated-board/head.toml, which the feeder renders in the guest.
#   make-reference-board.sh QEMU_VIRT_BOARD_TOML HEAD_TOML SCENE_TOML OUT_DIR
set -eu
mkdir -p "$4"
sed -e 's|^backend = "v4l2"|backend = "sim"|' -e 's|^device = "/dev/video[0-9]*"|device = "main"|' \
  -e 's|^exposure_us = 0.0 .*|exposure_us = 10000.0|' "$1" >"$4/board.toml"
cp "$2" "$4/head.toml"
cp "$3" "$4/scene.toml"
printf '\n[sim]\nhead = "head.toml"\nscene = "scene.toml"\nseed = 1\n' >>"$4/board.toml"
