// SPDX-License-Identifier: Apache-2.0
// The real clock: CLOCK_MONOTONIC, absolute sleeps with clock_nanosleep.
#pragma once

#include <chrono>

#include "drivers/clock.hpp"

namespace cylscan::drivers {

class MonotonicClock final : public Clock {
 public:
  std::chrono::nanoseconds now() const override;
  // clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME), resumed after signals
  // (EINTR): returns only once now() >= deadline.
  void sleepUntil(std::chrono::nanoseconds deadline) override;
};

}  // namespace cylscan::drivers
