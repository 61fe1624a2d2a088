# SPDX-License-Identifier: Apache-2.0
# Sourced by the scripts that assemble an arm64 root (the emulated board, the
# image): the kernel they boot and the Debian mirror they take packages from.
# The kernel: Debian bookworm-backports' 6.12 for arm64 (CYLSCAN_KERNEL_ABI
# picks another ABI of it).
kabi=${CYLSCAN_KERNEL_ABI:-6.12.95+deb12}
kver=$kabi-arm64
mirror=${CYLSCAN_DEBIAN_MIRROR:-http://deb.debian.org/debian}
