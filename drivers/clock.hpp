// SPDX-License-Identifier: Apache-2.0
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

  // Participation of the calling thread in the clock's time. A real clock
  // ignores it. A discrete-event clock (the virtual head's) advances only
  // when every participating thread waits on it, so a thread that takes part
  // in an acquisition (the step executor, the thread waiting for frames)
  // attaches for its whole work, with ClockThread. A participating thread
  // must not block outside the clock (join, a long-held mutex) without
  // detaching first, or virtual time stops. Calls nest.
  virtual void attachThread() {}
  virtual void detachThread() {}
};

// Attaches the calling thread to a clock for the guard's lifetime.
class ClockThread {
 public:
  explicit ClockThread(Clock& clock) : clock_(clock) { clock_.attachThread(); }
  ~ClockThread() { clock_.detachThread(); }
  ClockThread(const ClockThread&) = delete;
  ClockThread& operator=(const ClockThread&) = delete;

 private:
  Clock& clock_;
};

}  // namespace cylscan::drivers
