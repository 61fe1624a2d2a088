// SPDX-License-Identifier: Apache-2.0
// Which instruction-set variant of the fixed-point kernels runs.
//
// The kernels are written once, in portable C++ that the compiler vectorises,
// and built three times on x86-64: baseline ISA, AVX2 and AVX-512. All produce the
// same bits (integer arithmetic and IEEE-754 basic operations only), so the
// choice changes speed, never results. Tests pin each variant to check that.
#pragma once

namespace cylscan::algo {

enum class KernelIsa {
  kAuto,      // the widest of the variants below that the CPU has
  kBaseline,  // SSE2 on x86-64, NEON on aarch64, whatever the target's default is
  kAvx2,      // x86-64 only; resolves to the baseline where unavailable
  kAvx512,    // x86-64 only (AVX-512 F/BW/VL/DQ); resolves to kAvx2 or the baseline
};

// kAuto resolved for this CPU; an unavailable variant falls back to the next narrower one.
KernelIsa resolveKernelIsa(KernelIsa requested);

// True when the variant exists in this build and the CPU can run it.
bool avx2KernelsAvailable();
bool avx512KernelsAvailable();

}  // namespace cylscan::algo
