// SPDX-License-Identifier: Apache-2.0
// Which instruction-set variant of the fixed-point kernels runs.
//
// The kernels are written once, in portable C++ that the compiler vectorises,
// and built more than once: on x86-64 for the baseline ISA, AVX2 and AVX-512; on
// 32-bit ARM (Debian armhf, whose baseline VFPv3-D16 has no NEON) for the
// baseline and NEON. All produce the same bits (integer arithmetic and IEEE-754
// basic operations only), so the choice changes speed, never results. Tests pin
// each variant to check that.
#pragma once

#if defined(__arm__) && defined(__GNUC__) && defined(__linux__) && !defined(__ARM_NEON)
#define CYLSCAN_NEON_VARIANT 1
#else
#define CYLSCAN_NEON_VARIANT 0
#endif

namespace cylscan::algo {

enum class KernelIsa {
  kAuto,      // the widest of the variants below that the CPU has
  kBaseline,  // SSE2 on x86-64, NEON on aarch64, whatever the target's default is
  kAvx2,      // x86-64 only; resolves to the baseline where unavailable
  kAvx512,    // x86-64 only (AVX-512 F/BW/VL/DQ); resolves to kAvx2 or the baseline
  kNeon,      // 32-bit ARM builds without NEON in their baseline; else the baseline
};

// kAuto resolved for this CPU; an unavailable variant falls back to the next narrower one.
KernelIsa resolveKernelIsa(KernelIsa requested);

// True when the variant exists in this build and the CPU can run it.
bool avx2KernelsAvailable();
bool avx512KernelsAvailable();
bool neonKernelsAvailable();

}  // namespace cylscan::algo
