// SPDX-License-Identifier: Apache-2.0
#include "tools/checkerboard_corners.hpp"

#include <algorithm>
#include <filesystem>
#include <optional>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/input_error.hpp"
#include "formats/png.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;

// Any 8/16-bit, 1/3/4-channel PNG as 8-bit grey (16-bit stretched to its range).
cv::Mat readGrey8(const fs::path& file) {
  cv::Mat image = formats::readPng(file);
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2GRAY);
  if (image.channels() == 2) throw formats::InputError(file, "grey+alpha images are not supported");
  if (image.depth() == CV_8U) return image;
  cv::Mat grey;
  cv::normalize(image, grey, 0, 255, cv::NORM_MINMAX, CV_8U);
  return grey;
}

// The smallest distance between neighbouring corners, in pixels.
double cornerSpacing(const Corners& corners, cv::Size pattern) {
  double spacing = 1e9;
  const auto corner = [&](int r, int c) {
    return corners[static_cast<std::size_t>(r) * static_cast<std::size_t>(pattern.width) +
                   static_cast<std::size_t>(c)];
  };
  for (int r = 0; r < pattern.height; ++r) {
    for (int c = 0; c < pattern.width; ++c) {
      const cv::Point2f p = corner(r, c);
      if (c + 1 < pattern.width) spacing = std::min(spacing, cv::norm(p - corner(r, c + 1)));
      if (r + 1 < pattern.height) spacing = std::min(spacing, cv::norm(p - corner(r + 1, c)));
    }
  }
  return spacing;
}

std::optional<Corners> findCorners(const cv::Mat& grey, cv::Size pattern) {
  Corners corners;
  const int flags = cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE;
  if (!cv::findChessboardCorners(grey, pattern, corners, flags)) return std::nullopt;
  // The search window (2·half + 1 pixels) must stay inside one square.
  const int half = std::clamp(static_cast<int>(0.4 * cornerSpacing(corners, pattern)), 2, 11);
  cv::cornerSubPix(grey, corners, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-4));
  return corners;
}

// findChessboardCorners may start the grid at either end; the two cameras of a
// pair look the same way, so their first-to-last corner directions must agree.
void alignOrder(const Corners& main, Corners& aux) {
  const cv::Point2f dm = main.back() - main.front();
  const cv::Point2f da = aux.back() - aux.front();
  if (dm.dot(da) < 0) std::reverse(aux.begin(), aux.end());
}

}  // namespace

std::vector<cv::Point3f> boardPoints(const formats::CheckerboardInfo& board) {
  std::vector<cv::Point3f> points;
  for (int r = 0; r < board.rows; ++r) {
    for (int c = 0; c < board.cols; ++c) {
      points.emplace_back(static_cast<float>(c * board.square_mm),
                          static_cast<float>(r * board.square_mm), 0.0f);
    }
  }
  return points;
}

// Reads every pair, finds the corners; pairs without the board in both images
// are rejected. Images of main and aux must have one size.
std::vector<PairCorners> detectPairs(const formats::CheckerboardSet& set, cv::Size& size,
                                     std::vector<Rejection>& rejected) {
  const cv::Size pattern(set.board.cols, set.board.rows);
  std::vector<PairCorners> pairs;
  for (const auto& pair : set.pairs) {
    const cv::Mat main = readGrey8(pair.main);
    const cv::Mat aux = readGrey8(pair.aux);
    if (size.empty()) size = main.size();
    if (main.size() != size)
      throw formats::InputError(pair.main, "differs in size from the first pair");
    if (aux.size() != size) {
      throw formats::InputError(pair.aux, "differs in size from the main camera's images");
    }
    auto main_corners = findCorners(main, pattern);
    auto aux_corners = findCorners(aux, pattern);
    if (!main_corners || !aux_corners) {
      const std::string where = !main_corners && !aux_corners ? "main and aux"
                                : !main_corners               ? "main"
                                                              : "aux";
      rejected.push_back({pair.id, "corners not found in " + where});
      continue;
    }
    alignOrder(*main_corners, *aux_corners);
    pairs.push_back({pair.id, std::move(*main_corners), std::move(*aux_corners)});
  }
  return pairs;
}

}  // namespace cylscan::tools
