// The virtual head's clock: virtual time that sleepUntil advances instantly,
// or (paced) the real monotonic time since the head was made.
#pragma once

#include <atomic>
#include <chrono>

#include "drivers/clock.hpp"

namespace cylscan::sim {

class VirtualClock : public drivers::Clock {
 public:
  explicit VirtualClock(bool paced = false);
  std::chrono::nanoseconds now() const override;
  void sleepUntil(std::chrono::nanoseconds deadline) override;
  bool paced() const { return paced_; }

 private:
  bool paced_;
  std::chrono::steady_clock::time_point origin_;
  std::atomic<std::int64_t> now_ns_{0};
};

}  // namespace cylscan::sim
