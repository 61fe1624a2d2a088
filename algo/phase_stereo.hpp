// SPDX-License-Identifier: Apache-2.0
// Phase-based stereo (the paper's SV method, the reference geometry of the
// quasi-calibration): two calibrated cameras see the same absolute phase Φ;
// along an epipolar line the aux position of the main pixel's phase gives the
// disparity, and the two rays give the point.
//
// Design: the main map is never resampled. Every ORIGINAL main pixel keeps its
// own phase; its rectified coordinate (xr, yr) is computed once (undistort +
// R1 + P1, to convergence). The aux map is rectified once per call, with a
// NaN-aware bilinear resampling of our own (a sample is valid only when all
// source pixels with non-zero weight are valid; cv::remap would quantise the
// position to 1/32 pixel, i.e. up to ~0.1 mm of depth here). The epipolar
// line y = yr lies between two rectified aux rows r and r+1; the phase on it
// is their linear blend. Within monotone segments (precomputed per row pair:
// both rows valid and strictly monotone in the same direction, no step larger
// than max_phase_step_rad) the blend is monotone, so a binary search finds the
// bracketing pair, and linear interpolation the sub-pixel x. A phase found in
// more than one segment is ambiguous and rejected. The point is triangulated
// in the rectified frame and rotated back by R1ᵀ into the main camera frame,
// and stored at the original main pixel: no second resampling.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "algo/geometry.hpp"

namespace cylscan::algo {

// The stereo pair of docs/formats.md, stereo calibration file:
// X_aux = rotation·X_main + translation (mm).
struct StereoGeometry {
  PinholeCamera main;
  PinholeCamera aux;
  cv::Matx33d rotation = cv::Matx33d::eye();
  cv::Vec3d translation;
};

struct PhaseStereoOptions {
  // cv::stereoRectify free scaling. -1 is OpenCV's default, which keeps the
  // rectified sampling close to the cameras' own; 1 (keep every pixel) shrinks
  // the rectified focal length of a strongly verged pair, and the bilinear
  // resampling error of the aux phase grows as the square of the sample step
  // (measured on a 50 mm sphere at 320 px: worst 0.027 mm at 1, 0.004 at -1).
  double alpha = -1.0;
  double max_phase_step_rad = 1.0;  // a larger jump between neighbours is an edge, not a slope
};

struct PhaseStereoResult {
  cv::Mat xyz;                      // CV_32FC3 on the original main grid, NaN where unmatched
  std::vector<cv::Point3f> points;  // the matched points, row-major over the main pixels
  std::vector<cv::Point> pixels;    // the main pixel of each point
};

class PhaseStereo {
 public:
  // Precomputes the rectification (invalid_argument for different image
  // sizes or a vertical stereo pair).
  explicit PhaseStereo(const StereoGeometry& geometry, PhaseStereoOptions options = {});

  // Both maps CV_32F of the image size, absolute phase, NaN = invalid.
  PhaseStereoResult reconstruct(const cv::Mat& phase_main, const cv::Mat& phase_aux) const;

  // The aux phase on the rectified grid (CV_64F, NaN invalid); for tests and tools.
  cv::Mat rectifyAux(const cv::Mat& phase_aux) const;
  // (xr, yr) of every original main pixel (CV_64FC2).
  const cv::Mat& mainRectifiedCoordinates() const { return main_rectified_; }

 private:
  struct Segment {
    int begin = 0;  // first sample
    int end = 0;    // last sample (inclusive), end > begin
    bool increasing = true;
  };

  std::vector<std::vector<Segment>> segments(const cv::Mat& rectified, bool pairs) const;

  cv::Size size_;
  PhaseStereoOptions options_;
  cv::Mat main_rectified_;  // CV_64FC2
  cv::Mat aux_map_x_;       // CV_32F: rectified aux pixel → original aux x
  cv::Mat aux_map_y_;
  cv::Matx33d rect_to_main_;  // R1ᵀ
  double focal_ = 0.0;
  double cx_main_ = 0.0;
  double cx_aux_ = 0.0;
  double cy_ = 0.0;
  double p2_tx_ = 0.0;  // P2(0,3) = f·Tx
};

}  // namespace cylscan::algo
