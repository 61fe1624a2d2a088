// SPDX-License-Identifier: Apache-2.0
// The process's peak resident memory so far (VmHWM of /proc/self/status):
// what a scan or a solve needed at most, for the scan report and /metrics.
#pragma once

#include <sys/resource.h>

#include <cstdint>

namespace cylscan::firmware {

// Bytes; 0 when the kernel does not say.
inline std::uint64_t peakResidentBytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0 || usage.ru_maxrss < 0) return 0;
  return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024;  // Linux gives kB
}

}  // namespace cylscan::firmware
