#include "drivers/sim/virtual_clock.hpp"

#include <thread>

namespace cylscan::sim {

VirtualClock::VirtualClock(bool paced) : paced_(paced), origin_(std::chrono::steady_clock::now()) {}

std::chrono::nanoseconds VirtualClock::now() const {
  if (paced_) {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() -
                                                                origin_);
  }
  return std::chrono::nanoseconds{now_ns_.load(std::memory_order_acquire)};
}

void VirtualClock::sleepUntil(std::chrono::nanoseconds deadline) {
  if (paced_) {
    std::this_thread::sleep_until(origin_ + deadline);
    return;
  }
  std::int64_t current = now_ns_.load(std::memory_order_relaxed);
  while (current < deadline.count() &&
         !now_ns_.compare_exchange_weak(current, deadline.count(), std::memory_order_acq_rel)) {
  }
}

}  // namespace cylscan::sim
