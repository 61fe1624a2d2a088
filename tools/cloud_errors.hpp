// SPDX-License-Identifier: Apache-2.0
// Signed distances of a reconstructed cloud's points to the true surfaces,
// kept both as a list and on the main pixel grid (the cloud's u, v).
#pragma once

#include <filesystem>
#include <vector>

#include <opencv2/core.hpp>

#include "tools/scene_truth.hpp"

namespace cylscan::tools {

struct CloudErrors {
  std::vector<double> values_mm;  // one per finite point
  cv::Mat map_mm;                 // CV_32F of `grid`, NaN where no point
};

// InputError naming the cloud when it has no u, v properties or a u, v
// outside the grid.
CloudErrors cloudErrors(const std::filesystem::path& ply, const SceneTruth& truth, cv::Size grid);

// Points whose |distance| to every true surface exceeds `threshold_mm`.
std::size_t countFarther(const std::vector<double>& values_mm, double threshold_mm);

}  // namespace cylscan::tools
