// SPDX-License-Identifier: Apache-2.0
// The quasi-calibration (paper Eq. 10) from plane poses, each a capture
// bundle with the cameras main and aux: the solve behind `cylscan calibrate`
// and, on the head's own bundles, of a calibration the daemon runs.
//
// For each pose: the absolute phase of main and aux (the phase engine), the
// phase-based stereo points (PhaseStereo, main camera frame), a robust plane
// fit of those points (the noise-reduced reference geometry of the board),
// and the target XYZ of every valid main pixel = its viewing ray (intrinsics
// and distortion) ∩ the fitted plane. A main pixel counts when its phase is
// valid and its stereo point, if it has one, lies within the plane tolerance
// (a pixel aux cannot see still has a ray and a plane; with
// stereo_pixels_only it must have a stereo inlier).
//
// Memory: the poses are measured one at a time, each keeping only its masked
// phase map (4 bytes a pixel, ~3.2 MB at 1000×800) and its plane; the
// fitter's sums are made from those afterwards, so they never meet a pose's
// phase maps, and the targets are recomputed from the rays for the residual
// pass (Eq. 12), so no bundle is read twice.
#pragma once

#include <cstddef>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "algo/geometry.hpp"
#include "algo/phase_engine.hpp"
#include "algo/quasi_calibration.hpp"
#include "firmware/solve_progress.hpp"
#include "formats/stereo_calibration.hpp"

namespace cylscan::firmware {

struct QuasiSolveOptions {
  // The absolute phase modelled: Φ of the high set (the paper's) or the fused one.
  PhaseSource phase = PhaseSource::Fused;
  // Poses a pixel must be seen in, and poses needed (> 4: a cubic and a residual).
  int min_poses = 6;
  double plane_tolerance_mm = 0.5;  // stereo points farther from a pose's plane are outliers
  // Use only the main pixels with a stereo point on the plane.
  bool stereo_pixels_only = false;
  // Where the stereo calibration was read from: the file the InputError names
  // when a bundle's images are of another size. Empty: the bundle's camera
  // folder is named instead.
  std::filesystem::path stereo_file;
};

// One plane pose as the solve measured and then explained it.
struct QuasiPoseResult {
  std::string bundle;  // the bundle's folder
  // The fitted calibration against the pose's targets (algo::PoseResidual).
  double rmse_mm = 0;             // of Z
  double distance_rmse_mm = 0;    // of the 3D distance
  std::size_t pixels = 0;         // calibrated pixels of the pose
  std::size_t target_pixels = 0;  // main pixels the pose gave the fit
  // The pose's plane: its stereo points, the robust fit's inliers and RMSE.
  std::size_t stereo_points = 0;
  std::size_t plane_inliers = 0;
  double plane_rmse_mm = 0;
  algo::Plane plane;
  double main_valid_fraction = 0;
  double aux_valid_fraction = 0;
  algo::OrderResidual order_residual;  // main's
  double ms = 0;                       // measuring the pose
};

struct QuasiSolveTimings {
  double measure_ms = 0;    // the poses' phase, stereo points and planes
  double fit_ms = 0;        // the poses' targets into the fitter, and its fit
  double residuals_ms = 0;  // the residual pass
};

struct QuasiSolveResult {
  // With its residual summary (pooled RMSE, S_eff) and, when measured, the
  // order residual the poses numbered their orders about.
  algo::QuasiCalibration calibration;
  std::vector<QuasiPoseResult> poses;  // in the given order
  double pooled_rmse_mm = 0;           // σ_cal, Eq. (12)
  double pooled_distance_rmse_mm = 0;
  double sensitivity_mm_per_rad = 0;  // S_eff
  std::size_t residual_pixels = 0;    // P of Eq. (12)
  QuasiSolveTimings timings;
};

// Fewer plane poses than QuasiSolveOptions::min_poses (a bad request).
class TooFewPoses : public std::invalid_argument {
 public:
  TooFewPoses(std::size_t given, int needed);
  std::size_t given() const { return given_; }
  int needed() const { return needed_; }

 private:
  std::size_t given_;
  int needed_;
};

// No pixel was seen, valid, in min_poses poses: nothing to calibrate.
class NoPixelCalibrated : public std::runtime_error {
 public:
  explicit NoPixelCalibrated(int min_poses);
};

// TooFewPoses unless `given` poses are enough for `min_poses`.
void requireEnoughPoses(std::size_t given, int min_poses);

// The solve over the bundles, read once each, in the order given. Throws
// TooFewPoses, formats::InputError naming the bundle (unreadable, no main or
// aux, images of another size than the calibration's, too few stereo points
// for a plane) or the frame, NoPixelCalibrated. `progress` counts the poses
// measured, then the fit and the residual pass.
QuasiSolveResult solveQuasiCalibration(const formats::StereoCalibration& stereo,
                                       const std::vector<std::filesystem::path>& bundles,
                                       const QuasiSolveOptions& options = {},
                                       const SolveProgress& progress = {});

// One pose's figures as `cylscan calibrate --json` reports them (docs/formats.md).
nlohmann::json quasiPoseJson(const QuasiPoseResult& pose);

}  // namespace cylscan::firmware
