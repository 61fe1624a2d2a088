// The real clock of a board: CLOCK_MONOTONIC, the clock of the kernel's GPIO
// edge and V4L2 buffer timestamps.
#pragma once

#include <chrono>

#include "drivers/clock.hpp"

namespace cylscan::drivers {

class MonotonicClock final : public Clock {
 public:
  std::chrono::nanoseconds now() const override;
  // clock_nanosleep to an absolute deadline (resumed after signals).
  void sleepUntil(std::chrono::nanoseconds deadline) override;
};

}  // namespace cylscan::drivers
