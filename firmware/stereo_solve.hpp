// SPDX-License-Identifier: Apache-2.0
// The stereo calibration of the main and aux cameras from checkerboard pairs:
// the solve behind `cylscan calibrate-stereo`, on data in memory so that a
// calibration on the head (the daemon's) runs the same code.
//
// Each camera: cv::calibrateCamera (the distortion model's coefficients) on
// the pairs where both cameras found the board; a pair whose view reprojects
// worse than max(3 × median, 0.5 px) in either camera is an outlier, dropped,
// and both cameras are calibrated again without it. The pair:
// cv::stereoCalibrate with CALIB_FIX_INTRINSIC, i.e. only R and T (6
// parameters) are estimated from all pairs. Why not a joint refinement: each
// camera's intrinsics are already fitted to every usable view of that camera,
// the extrinsics then come from a small, well-conditioned problem, and a
// camera's RMS stays the RMS of the intrinsics that are returned.
// refine_jointly runs the joint refinement (CALIB_USE_INTRINSIC_GUESS) for
// comparison; a camera's RMS is then the joint model's, the one returned (the
// parameters' sigmas stay those of the separate fits, the only ones OpenCV
// estimates).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "firmware/checkerboard_corners.hpp"
#include "firmware/solve_progress.hpp"
#include "formats/checkerboard_set.hpp"
#include "formats/stereo_calibration.hpp"

namespace cylscan::firmware {

struct StereoSolveOptions {
  // Usable pairs needed, counted again after dropping the reprojection outliers.
  int min_pairs = 6;
  // The distortion coefficients estimated: "k1k2p1p2k3", "k1k2p1p2" or "k1k2"
  // (the others are 0); std::invalid_argument for another name.
  std::string model = "k1k2p1p2k3";
  // Refine the intrinsics together with R and T instead of fixing them.
  bool refine_jointly = false;
};

// One standard deviation of each intrinsic (cv::calibrateCamera's estimate
// from the residuals): how well the views determine it. 0 for a coefficient
// the model fixes.
struct IntrinsicSigmas {
  double fx = 0, fy = 0, cx = 0, cy = 0;  // px
  cv::Vec<double, 5> dist_coeffs;         // k1 k2 p1 p2 k3
};

struct StereoCameraResult {
  cv::Matx33d camera_matrix;  // as in the calibration
  cv::Vec<double, 5> dist_coeffs;
  double rms_px = 0;  // over the pairs used
  IntrinsicSigmas sigma;
};

// One pair used, its RMS reprojection error in each camera and in the pair's fit.
struct StereoViewResult {
  std::string id;
  double main_rms_px = 0;
  double aux_rms_px = 0;
  double stereo_rms_px = 0;  // √((main² + aux²)/2) of cv::stereoCalibrate's views
};

struct StereoSolveResult {
  formats::StereoCalibration calibration;
  cv::Size image_size;
  std::size_t pair_count = 0;  // pairs given
  StereoCameraResult main;
  StereoCameraResult aux;
  double stereo_rms_px = 0;             // cv::stereoCalibrate's, both cameras
  double baseline_mm = 0;               // |T|
  std::vector<StereoViewResult> views;  // the pairs used, in the given order
  // The pairs left out with the reason: the board not found (first, in the
  // given order), then the reprojection outliers.
  std::vector<Rejection> rejected;
};

// The board was found in none of the pairs given: most often cols × rows
// counts squares, not inner corners.
class BoardNotFound : public std::runtime_error {
 public:
  BoardNotFound(const formats::CheckerboardInfo& board, std::size_t pair_count);
  std::size_t pairCount() const { return pair_count_; }

 private:
  std::size_t pair_count_;
};

// Fewer usable pairs than StereoSolveOptions::min_pairs; nothing was solved.
class TooFewPairs : public std::runtime_error {
 public:
  TooFewPairs(std::size_t usable, int needed, bool after_outliers, std::vector<Rejection> rejected);
  std::size_t usable() const { return usable_; }
  int needed() const { return needed_; }
  // Whether the count fell short only once the reprojection outliers were dropped.
  bool afterOutliers() const { return after_outliers_; }
  // Every pair left out so far and why.
  const std::vector<Rejection>& rejected() const { return rejected_; }
  // "; <id>: <reason>" for each rejected pair.
  std::string reasons() const;

 private:
  std::size_t usable_;
  int needed_;
  bool after_outliers_;
  std::vector<Rejection> rejected_;
};

// The solve on corners already found (detectStereoCorners). Throws
// BoardNotFound when pairs were examined and none had the board in both
// images, TooFewPairs, std::invalid_argument for a bad option.
StereoSolveResult solveStereo(const formats::CheckerboardInfo& board, StereoCorners corners,
                              const StereoSolveOptions& options = {},
                              const SolveProgress& progress = {});

// Detection (the first half of `progress`), then the solve; also
// std::invalid_argument naming the pair for an image that cannot be used.
StereoSolveResult solveStereo(const formats::CheckerboardInfo& board,
                              const std::vector<StereoPairImages>& pairs,
                              const StereoSolveOptions& options = {},
                              const SolveProgress& progress = {});

}  // namespace cylscan::firmware
