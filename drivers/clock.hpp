// Monotonic time for the executor: the real CLOCK_MONOTONIC, or the virtual
// head's clock, which can run as fast as the CPU allows.
#pragma once

#include <chrono>

namespace cylscan::drivers {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual std::chrono::nanoseconds now() const = 0;
  // Sleeps until the absolute time `deadline` (no-op when it has passed).
  virtual void sleepUntil(std::chrono::nanoseconds deadline) = 0;
};

}  // namespace cylscan::drivers
