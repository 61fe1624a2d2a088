// SPDX-License-Identifier: Apache-2.0
// The checkerboard corners of a stereo calibration, found and refined in both
// cameras of each pair: from images in memory (the head's own captures) or
// from a checkerboard set on disk (docs/formats.md, checkerboard set).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "firmware/solve_progress.hpp"
#include "formats/checkerboard_set.hpp"

namespace cylscan::firmware {

using Corners = std::vector<cv::Point2f>;

// A pair left out of the solve and why.
struct Rejection {
  std::string id;
  std::string reason;
};

struct PairCorners {
  std::string id;
  Corners main;
  Corners aux;
};

// One checkerboard pair as the cameras took it: any 8/16-bit image with 1, 3
// or 4 channels (16-bit is stretched to its range).
struct StereoPairImages {
  std::string id;
  cv::Mat main;
  cv::Mat aux;
};

// What the detection found in the pairs.
struct StereoCorners {
  cv::Size image_size;              // every image's; empty when there was no pair
  std::vector<PairCorners> pairs;   // the board found in both images
  std::vector<Rejection> rejected;  // the others, "corners not found in main|aux|main and aux"
  std::size_t pair_count = 0;       // pairs examined
};

// One pair's corners, each nullopt where the board was not found; when both
// are found, aux's run in main's order.
struct PairDetection {
  std::optional<Corners> main;
  std::optional<Corners> aux;

  bool found() const { return main && aux; }
  // "main", "aux" or "main and aux"; empty when found().
  std::string missing() const;
};

// The board's inner corners in its own frame (mm, z = 0), row by row.
std::vector<cv::Point3f> boardPoints(const formats::CheckerboardInfo& board);

// The image as 8-bit grey (16-bit stretched to its range);
// std::invalid_argument for an empty or a grey+alpha image.
cv::Mat toGrey8(const cv::Mat& image);

// The corners in both images of a pair (cv::findChessboardCorners, then
// cv::cornerSubPix with a window inside one square). std::invalid_argument
// when the images differ in size or one cannot be made grey (toGrey8).
PairDetection detectPairCorners(const formats::CheckerboardInfo& board, const cv::Mat& main,
                                const cv::Mat& aux);

// Every pair's corners; std::invalid_argument naming the pair when an image
// is empty, not grey-able or of another size than the first pair's.
// `progress` goes from 0 to 1 over the pairs.
StereoCorners detectStereoCorners(const formats::CheckerboardInfo& board,
                                  const std::vector<StereoPairImages>& pairs,
                                  const SolveProgress& progress = {});

// The same for a checkerboard set on disk, one pair in memory at a time;
// InputError naming the file for an unreadable image or one of another size.
StereoCorners detectStereoCorners(const formats::CheckerboardSet& set);

}  // namespace cylscan::firmware
