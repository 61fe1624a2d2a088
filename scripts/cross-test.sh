#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Cross-builds cylscan for an ARM target and runs, under qemu-user, the test
# suites that prove the target computes the same bits as the host:
#   scripts/cross-test.sh [aarch64|armhf]        (default aarch64)
# 1. installs the cross compilers, qemu-user and mmdebstrap (toolchain/install-cross.sh);
# 2. makes the target's sysroot, cached in build/sysroot-<arch> (toolchain/make-sysroot.sh);
# 3. builds the host's cylscan_bit_identity and records its digests of the
#    fixed-point phase, reconstruction and calibration file for a synthetic scan;
# 4. cross-builds cylscan, algo_tests, formats_tests and cylscan_bit_identity
#    (cmake --preset <arch>), the last compared with the host's digests,
#    without the virtual head (CYLSCAN_WITH_SIM=OFF): none of them needs it,
#    and this is the build that proves a board's build without it compiles;
# 5. runs them with ctest (labels algo, formats, bit_identity) under
#    qemu-user -L <sysroot> and prints its summary.
# 6. with CROSS_PACKAGE=1, also builds the target's package (programs, page;
#    no tests) in <CROSS_BUILD_DIR>-package and checks its architecture and
#    that its Depends came from the target's libraries.
# Environment: CROSS_BUILD_DIR (default build/cross-<arch>), HOST_BUILD_DIR
# (build/cross-host; an existing Release build is used as it is),
# CROSS_TEST_LABELS (default 'algo|formats|bit_identity'),
# CROSS_TEST_TARGETS (extra targets to build, e.g. "backends_tests"), CROSS_PACKAGE.
set -euo pipefail
# shellcheck disable=SC2317 # the build steps are functions run through `timed`

arch=${1:-aarch64}
case "$arch" in
  aarch64 | armhf) ;;
  *) echo "usage: $0 [aarch64|armhf]" >&2; exit 2 ;;
esac
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
sysroot=$root/build/sysroot-$arch
cross_dir=${CROSS_BUILD_DIR:-build/cross-$arch}
host_dir=${HOST_BUILD_DIR:-build/cross-host}
labels=${CROSS_TEST_LABELS:-algo|formats|bit_identity}
cross_dir=$(realpath -m "$cross_dir")
host_dir=$(realpath -m "$host_dir")
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi

t0=$SECONDS
step() { printf '\n== cross-test %s: %s (%ds)\n' "$arch" "$1" $((SECONDS - t0)); }
declare -A took
timed() {
  local name=$1; shift
  local s=$SECONDS status=0
  "$@" || status=$?
  took[$name]=$((SECONDS - s))
  return "$status"
}

step "host packages"
timed install bash -c "scripts/install-deps.sh && toolchain/install-cross.sh $arch"

step "sysroot $sysroot"
timed sysroot toolchain/make-sysroot.sh "$arch" "$sysroot"

step "host reference digests"
host_build() {
  # An existing Release build (test.sh passes the suite's) is used as it is.
  if [ ! -f "$host_dir/CMakeCache.txt" ]; then
    cmake -S . -B "$host_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" \
      -DCYLSCAN_BUILD_BENCH=OFF -DCYLSCAN_BUILD_WEB=OFF >/dev/null
  fi
  if ! grep -q '^CMAKE_BUILD_TYPE:STRING=Release$' "$host_dir/CMakeCache.txt"; then
    echo "cross-test: $host_dir is not a Release build (the reference digests need one)" >&2
    return 1
  fi
  cmake --build "$host_dir" -j"$(nproc)" --target cylscan_bit_identity
  "$host_dir/tests/packaging/cylscan_bit_identity" >"$host_dir/bit-identity-host.txt"
}
timed host host_build
reference=$host_dir/bit-identity-host.txt

step "cross build ($cross_dir)"
cross_build() {
  cmake --preset "$arch" -B "$cross_dir" "${launcher[@]}" -DCYLSCAN_SYSROOT="$sysroot" \
    -DCYLSCAN_BUILD_WEB=OFF -DCYLSCAN_WITH_SIM=OFF -DCYLSCAN_BIT_IDENTITY_REFERENCE="$reference" \
    >/dev/null
  # shellcheck disable=SC2086 # CROSS_TEST_TARGETS is a list
  cmake --build "$cross_dir" -j"$(nproc)" --target cylscan algo_tests formats_tests \
    cylscan_bit_identity ${CROSS_TEST_TARGETS:-}
}
timed build cross_build
file "$cross_dir/tools/cylscan"

step "tests under qemu-user"
qemu="qemu-aarch64"
if [ "$arch" = armhf ]; then qemu="qemu-arm"; fi
"$qemu" -L "$sysroot" "$cross_dir/tools/cylscan" --version
rc=0
timed tests ctest --test-dir "$cross_dir" -L "$labels" -j"$(nproc)" --output-on-failure \
  --no-tests=error || rc=$?

if [ "${CROSS_PACKAGE:-0}" = 1 ]; then
  step "package"
  cross_package() {
    local dir=$cross_dir-package debarch=arm64 deb depends
    if [ "$arch" = armhf ]; then debarch=armhf; fi
    cmake --preset "$arch" -B "$dir" "${launcher[@]}" -DCYLSCAN_SYSROOT="$sysroot" \
      -DCYLSCAN_BUILD_TESTS=OFF >/dev/null
    cmake --build "$dir" -j"$(nproc)"
    (cd "$dir" && cpack -G DEB -B "$dir/package") | tail -n 2
    deb=$(ls "$dir"/package/cylscan_*_"$debarch".deb)
    depends=$(dpkg-deb -f "$deb" Depends)
    echo "$deb: Depends: $depends"
    [ "$(dpkg-deb -f "$deb" Architecture)" = "$debarch" ] &&
      grep -q "libc6 (>=" <<<"$depends" && grep -q "libopencv-core406" <<<"$depends"
  }
  timed package cross_package || rc=1
fi

printf '\ncross-test %s: install %ss, sysroot %ss, host reference %ss, cross build %ss, tests %ss%s; total %ss\n' \
  "$arch" "${took[install]}" "${took[sysroot]}" "${took[host]}" "${took[build]}" \
  "${took[tests]:-?}" "${took[package]:+, package ${took[package]}s}" $((SECONDS - t0))
exit "$rc"
