// SPDX-License-Identifier: Apache-2.0
// The two fringe sets of a scan and their executed stage angles (docs/formats.md,
// capture bundle).
#pragma once

#include <string_view>
#include <vector>

namespace cylscan::algo {

// "high": the short slot interval θh; "low": the long one θl.
enum class FringeSet { High, Low };

// One set as executed: its slot period and the stage angle of every frame.
struct FringeSetGeometry {
  double period_deg = 0;
  std::vector<double> stage_deg;  // executed angles, one per frame
};

constexpr std::string_view fringeSetName(FringeSet set) {
  return set == FringeSet::High ? "high" : "low";
}

}  // namespace cylscan::algo
