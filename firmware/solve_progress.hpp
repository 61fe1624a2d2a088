// SPDX-License-Identifier: Apache-2.0
// How far a calibration solve is, for a caller that shows it (the daemon's
// calibration session): the fraction done, from 0 to 1.
#pragma once

#include <algorithm>
#include <functional>
#include <utility>

namespace cylscan::firmware {

// Called on the solving thread with the fraction done in [0, 1], never
// decreasing, 1 last when the solve succeeds. An exception it throws ends the
// solve (a caller's way to cancel) and reaches the solve's caller.
using SolveProgress = std::function<void(double)>;

// A part [begin, end] of a caller's progress: a step reports its own 0 to 1
// and the caller sees it mapped into its span, never going back.
class ProgressSpan {
 public:
  ProgressSpan(const SolveProgress& progress, double begin, double end)
      : progress_(&progress), begin_(begin), end_(end) {}

  // Reports the step's own fraction `done` (clamped to [0, 1]).
  void operator()(double done) {
    const double at = begin_ + (end_ - begin_) * std::clamp(done, 0.0, 1.0);
    if (!*progress_ || at <= last_) return;
    last_ = at;
    (*progress_)(at);
  }

  // This span's part [begin, end] of the step (both in [0, 1]) as a
  // SolveProgress of its own, for a step made of steps.
  SolveProgress part(double begin, double end) {
    return [this, begin, end](double done) {
      (*this)(begin + (end - begin) * std::clamp(done, 0.0, 1.0));
    };
  }

 private:
  const SolveProgress* progress_;
  double begin_;
  double end_;
  double last_ = -1.0;
};

}  // namespace cylscan::firmware
