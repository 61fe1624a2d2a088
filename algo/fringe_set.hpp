// SPDX-License-Identifier: Apache-2.0
// The executed stage angles of a fringe set (docs/formats.md, capture bundle).
#pragma once

#include <vector>

#include "common/vocabulary.hpp"

namespace cylscan::algo {

// One set as executed: its slot period and the stage angle of every frame.
struct FringeSetGeometry {
  double period_deg = 0;
  std::vector<double> stage_deg;  // executed angles, one per frame
};

}  // namespace cylscan::algo
