#include "drivers/clock_monotonic.hpp"

#include <cerrno>
#include <ctime>

namespace cylscan::drivers {

std::chrono::nanoseconds MonotonicClock::now() const {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec);
}

void MonotonicClock::sleepUntil(std::chrono::nanoseconds deadline) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline.count() / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(deadline.count() % 1'000'000'000);
  if (deadline.count() < 0) return;
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace cylscan::drivers
