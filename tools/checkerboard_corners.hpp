// SPDX-License-Identifier: Apache-2.0
// Shared by calibrate-stereo and refine-stereo: the checkerboard corners of a
// checkerboard set (docs/formats.md, checkerboard set), found and refined in
// both cameras of each pair.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "formats/checkerboard_set.hpp"

namespace cylscan::tools {

using Corners = std::vector<cv::Point2f>;

struct Rejection {
  std::string id;
  std::string reason;
};

struct PairCorners {
  std::string id;
  Corners main;
  Corners aux;
};

// The board's inner corners in its own frame (mm, z = 0), row by row.
std::vector<cv::Point3f> boardPoints(const formats::CheckerboardInfo& board);

// Reads every pair and finds the corners (cv::findChessboardCorners, then
// cv::cornerSubPix with a window inside one square); pairs without the board
// in both images are added to `rejected`. `size` is set from the first image;
// InputError for images of another size or an unreadable file.
std::vector<PairCorners> detectPairs(const formats::CheckerboardSet& set, cv::Size& size,
                                     std::vector<Rejection>& rejected);

}  // namespace cylscan::tools
