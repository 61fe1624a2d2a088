// SPDX-License-Identifier: Apache-2.0
#include "algo/kernel_isa.hpp"

#if CYLSCAN_NEON_VARIANT
#include <asm/hwcap.h>
#include <sys/auxv.h>
#endif

namespace cylscan::algo {

bool avx2KernelsAvailable() {
#if defined(__x86_64__) && defined(__GNUC__)
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}

bool avx512KernelsAvailable() {
#if defined(__x86_64__) && defined(__GNUC__)
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq");
#else
  return false;
#endif
}

bool neonKernelsAvailable() {
#if CYLSCAN_NEON_VARIANT
  // The kernel's word for what the CPU has; ARMv7 cores without NEON exist
  // (Cortex-A9 parts such as NVIDIA's Tegra 2), so it is asked, not assumed.
  return (getauxval(AT_HWCAP) & HWCAP_NEON) != 0;
#else
  return false;
#endif
}

KernelIsa resolveKernelIsa(KernelIsa requested) {
  switch (requested) {
    case KernelIsa::kBaseline:
      return KernelIsa::kBaseline;
    case KernelIsa::kNeon:
      return neonKernelsAvailable() ? KernelIsa::kNeon : KernelIsa::kBaseline;
    case KernelIsa::kAuto:
      if (neonKernelsAvailable()) return KernelIsa::kNeon;
      [[fallthrough]];
    case KernelIsa::kAvx512:
      if (avx512KernelsAvailable()) return KernelIsa::kAvx512;
      [[fallthrough]];
    case KernelIsa::kAvx2:
      return avx2KernelsAvailable() ? KernelIsa::kAvx2 : KernelIsa::kBaseline;
  }
  return KernelIsa::kBaseline;
}

}  // namespace cylscan::algo
