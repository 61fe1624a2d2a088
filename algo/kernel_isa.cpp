// SPDX-License-Identifier: Apache-2.0
#include "algo/kernel_isa.hpp"

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

KernelIsa resolveKernelIsa(KernelIsa requested) {
  if (requested == KernelIsa::kBaseline) return KernelIsa::kBaseline;
  if ((requested == KernelIsa::kAuto || requested == KernelIsa::kAvx512) &&
      avx512KernelsAvailable()) {
    return KernelIsa::kAvx512;
  }
  return avx2KernelsAvailable() ? KernelIsa::kAvx2 : KernelIsa::kBaseline;
}

}  // namespace cylscan::algo
