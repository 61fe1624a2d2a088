// SPDX-License-Identifier: Apache-2.0
#include "drivers/clock_monotonic.hpp"

#include <cerrno>
#include <ctime>
#include <system_error>

namespace cylscan::drivers {

namespace {

constexpr long kNsPerSecond = 1'000'000'000;

}  // namespace

std::chrono::nanoseconds MonotonicClock::now() const {
  timespec ts{};
  if (clock_gettime(CLOCK_MONOTONIC, &ts) != 0) {
    throw std::system_error(errno, std::generic_category(), "clock_gettime(CLOCK_MONOTONIC)");
  }
  return std::chrono::nanoseconds{static_cast<std::int64_t>(ts.tv_sec) * kNsPerSecond + ts.tv_nsec};
}

void MonotonicClock::sleepUntil(std::chrono::nanoseconds deadline) {
  const std::int64_t ns = deadline.count();
  if (ns <= 0) return;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / kNsPerSecond);
  ts.tv_nsec = static_cast<long>(ns % kNsPerSecond);
  for (;;) {
    // Returns the error number (not errno); EINTR: a signal, sleep again
    // towards the same absolute deadline.
    const int rc = clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    if (rc == 0) return;
    if (rc != EINTR) throw std::system_error(rc, std::generic_category(), "clock_nanosleep");
  }
}

}  // namespace cylscan::drivers
