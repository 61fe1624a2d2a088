// SPDX-License-Identifier: Apache-2.0
// The two fringe sets that every measurement of the phase engine in bench/
// uses, so that the benchmark and the instruction count time the same work:
// 25 frames a set, the head's slot periods (5° high, 5.625° low), each frame's
// angle a whole number of 0.004° stage steps.
#pragma once

#include <cmath>

#include "algo/fringe_set.hpp"

namespace cylscan::bench {

constexpr int kFramesPerSet = 25;

inline algo::FringeSetGeometry fringeSet(double period_deg, double start_deg) {
  algo::FringeSetGeometry g{period_deg, {}};
  for (int k = 0; k < kFramesPerSet; ++k) {
    g.stage_deg.push_back(start_deg + std::round(period_deg * k / kFramesPerSet / 0.004) * 0.004);
  }
  return g;
}

inline algo::FringeSetGeometry highSet() {
  return fringeSet(5.0, -90.0);
}
inline algo::FringeSetGeometry lowSet() {
  return fringeSet(5.625, 87.0);
}

}  // namespace cylscan::bench
