// SPDX-License-Identifier: Apache-2.0
#include "firmware/checkerboard_corners.hpp"

#include <algorithm>
#include <filesystem>
#include <optional>
#include <stdexcept>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/input_error.hpp"
#include "formats/png.hpp"
#include "formats/size_text.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;

// Any 8/16-bit, 1/3/4-channel PNG as 8-bit grey (16-bit stretched to its range).
cv::Mat readGrey8(const fs::path& file) {
  const cv::Mat image = formats::readPng(file);
  if (image.channels() == 2) throw formats::InputError(file, "grey+alpha images are not supported");
  return toGrey8(image);
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

// The detection of two grey images of one size.
PairDetection detectGrey(cv::Size pattern, const cv::Mat& main, const cv::Mat& aux) {
  PairDetection found{findCorners(main, pattern), findCorners(aux, pattern)};
  if (found.found()) alignOrder(*found.main, *found.aux);
  return found;
}

// Adds the pair to `out` as its detection says.
void record(StereoCorners& out, const std::string& id, PairDetection found) {
  if (found.found()) {
    out.pairs.push_back({id, std::move(*found.main), std::move(*found.aux)});
  } else {
    out.rejected.push_back({id, "corners not found in " + found.missing()});
  }
}

}  // namespace

std::string PairDetection::missing() const {
  if (!main && !aux) return "main and aux";
  if (!main) return "main";
  if (!aux) return "aux";
  return "";
}

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

cv::Mat toGrey8(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("empty image");
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    throw std::invalid_argument("only 8-bit and 16-bit images are supported");
  }
  cv::Mat grey;
  switch (image.channels()) {
    case 1:
      grey = image;
      break;
    case 3:
      cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
      break;
    case 4:
      cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
      break;
    default:
      throw std::invalid_argument("grey+alpha images are not supported");
  }
  if (grey.depth() == CV_8U) return grey;
  cv::Mat eight;
  cv::normalize(grey, eight, 0, 255, cv::NORM_MINMAX, CV_8U);
  return eight;
}

PairDetection detectPairCorners(const formats::CheckerboardInfo& board, const cv::Mat& main,
                                const cv::Mat& aux) {
  const cv::Mat main_grey = toGrey8(main);
  const cv::Mat aux_grey = toGrey8(aux);
  if (main.size() != aux.size()) {
    throw std::invalid_argument("the aux image is " + formats::sizeText(aux.size()) +
                                ", main's is " + formats::sizeText(main.size()));
  }
  return detectGrey({board.cols, board.rows}, main_grey, aux_grey);
}

StereoCorners detectStereoCorners(const formats::CheckerboardInfo& board,
                                  const std::vector<StereoPairImages>& pairs,
                                  const SolveProgress& progress) {
  ProgressSpan report(progress, 0.0, 1.0);
  report(0.0);
  StereoCorners out;
  out.pair_count = pairs.size();
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const StereoPairImages& pair = pairs[i];
    if (out.image_size.empty()) out.image_size = pair.main.size();
    if (pair.main.size() != out.image_size) {
      throw std::invalid_argument("checkerboard pair " + pair.id + ": the main image is " +
                                  formats::sizeText(pair.main.size()) + ", the first pair's are " +
                                  formats::sizeText(out.image_size));
    }
    try {
      record(out, pair.id, detectPairCorners(board, pair.main, pair.aux));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("checkerboard pair " + pair.id + ": " + e.what());
    }
    report(static_cast<double>(i + 1) / static_cast<double>(pairs.size()));
  }
  report(1.0);
  return out;
}

StereoCorners detectStereoCorners(const formats::CheckerboardSet& set) {
  const cv::Size pattern(set.board.cols, set.board.rows);
  StereoCorners out;
  out.pair_count = set.pairs.size();
  for (const auto& pair : set.pairs) {
    const cv::Mat main = readGrey8(pair.main);
    const cv::Mat aux = readGrey8(pair.aux);
    if (out.image_size.empty()) out.image_size = main.size();
    if (main.size() != out.image_size)
      throw formats::InputError(pair.main, "differs in size from the first pair");
    if (aux.size() != out.image_size) {
      throw formats::InputError(pair.aux, "differs in size from the main camera's images");
    }
    record(out, pair.id, detectGrey(pattern, main, aux));
  }
  return out;
}

}  // namespace cylscan::firmware
