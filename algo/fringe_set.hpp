// SPDX-License-Identifier: Apache-2.0
// The executed stage angles of a fringe set (docs/formats.md, capture bundle).
#pragma once

#include <vector>

#include "common/vocabulary.hpp"

namespace cylscan::algo {

// A set's slot in the engine's per-set arrays: high 0, low 1.
constexpr int fringeSetIndex(FringeSet set) {
  return set == FringeSet::High ? 0 : 1;
}

// One set as executed: its slot period and the stage angle of every frame.
struct FringeSetGeometry {
  double period_deg = 0;
  std::vector<double> stage_deg;  // executed angles, one per frame
};

}  // namespace cylscan::algo
