// SPDX-License-Identifier: Apache-2.0
// Wall-clock timing of the steps a command or a calibration solve reports.
#pragma once

#include <chrono>

namespace cylscan::firmware {

class Stopwatch {
 public:
  using Clock = std::chrono::steady_clock;

  Stopwatch() : start_(Clock::now()) {}
  double elapsedMs() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }
  // The time since the start (or the last lap), then starts again.
  double lapMs() {
    const auto now = Clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - start_).count();
    start_ = now;
    return ms;
  }

 private:
  Clock::time_point start_;
};

}  // namespace cylscan::firmware
