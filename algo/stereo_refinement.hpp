// SPDX-License-Identifier: Apache-2.0
// Refining the stereo pair with the phase: a checkerboard
// calibration leaves errors of ~0.1 % in focal length and hundredths of a
// degree in rotation, which the quasi-calibration copies into every point.
// The plane poses carry far denser and more precise correspondences: at every
// main pixel of a pose, the aux camera sees the same absolute phase, and the
// surface is a plane.
//
// The adjustment (Gauss–Newton with Levenberg–Marquardt damping on the normal
// equations, solved with Eigen) estimates, jointly:
//   - both cameras' intrinsics (the distortion model chosen by the caller),
//   - the pair's R and T,
//   - every checkerboard view's pose (in the main frame),
//   - every plane pose's plane,
// from two kinds of residuals:
//   - checkerboard reprojection, main and aux (pixels): they fix the metric
//     scale (the board's square size) and what the phase cannot see;
//   - phase consistency (aux pixels across the fringes): a main pixel's ray
//     meets its pose's plane at X; X projected into aux must see the main
//     pixel's absolute phase: r = (Φaux(π_aux(X)) − Φmain(u)) / |∇Φaux|.
// Each kind is weighted by its own RMS (re-estimated once after a first
// solve: a variance-component estimate), and phase samples whose residual is
// more than `outlier_sigmas` robust sigmas from zero are dropped before the
// second solve. Derivatives are central differences per parameter block; the
// normal matrix is dense but small (24 + 6·boards + 3·poses unknowns).
//
// What it can and cannot fix (measured on the virtual head, docs/validation.md):
// equal-phase correspondences on planes are unchanged by any change of the
// pair that maps planes to planes (a projective ambiguity), so they pin the
// distortion and the pair's mutual consistency but not the focal lengths or
// principal points, which set the depth scale and the frame; those stay as
// well (or as badly) determined as the checkerboard views make them.
//
// Pure computation: maps and corner lists in, geometry out.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "algo/geometry.hpp"
#include "algo/phase_stereo.hpp"

namespace cylscan::algo {

// One checkerboard view seen by both cameras; corners in the order of the
// board's object points.
struct CheckerboardView {
  std::vector<cv::Point2f> main;
  std::vector<cv::Point2f> aux;
};

struct CheckerboardObservations {
  std::vector<cv::Point3f> object;  // corners on the board (mm, z = 0)
  std::vector<CheckerboardView> views;
};

// One plane pose seen by both cameras.
struct PlanePoseObservation {
  cv::Mat phase_main;  // CV_32F absolute phase, NaN invalid
  cv::Mat phase_aux;   // CV_32F absolute phase, NaN invalid
  cv::Mat use;  // CV_8U: main pixels that may be sampled (e.g. stereo plane inliers); empty = all
  Plane plane;  // the initial plane (e.g. a robust fit of the phase-stereo points)
};

struct StereoRefinementOptions {
  // Distortion coefficients estimated for both cameras: "k1k2", "k1k2p1p2"
  // or "k1k2p1p2k3"; the others keep their initial values.
  std::string model = "k1k2p1p2k3";
  int samples_per_pose = 3000;  // main pixels sampled per plane pose (a regular grid)
  int max_iterations = 50;      // per solve
  double outlier_sigmas = 5.0;
};

struct ResidualSummary {
  double board_main_rms_px = 0;
  double board_aux_rms_px = 0;
  double phase_rms_px = 0;  // across-fringe aux pixels
  std::size_t phase_samples = 0;
};

struct StereoRefinementResult {
  StereoGeometry geometry;
  std::vector<Plane> planes;              // refined, one per pose
  ResidualSummary before;                 // at the initial geometry (all sampled points)
  ResidualSummary after;                  // at the refined geometry (inliers)
  std::vector<double> pose_phase_rms_px;  // after, per pose
  int iterations = 0;
  bool converged = false;
  std::size_t unknowns = 0;
};

// std::invalid_argument when there are fewer than 3 checkerboard views or 2
// plane poses, when maps differ from the geometry's image size, or when the
// model name is unknown; std::runtime_error when a pose has no usable sample.
StereoRefinementResult refineStereoWithPhase(const StereoGeometry& initial,
                                             const CheckerboardObservations& boards,
                                             const std::vector<PlanePoseObservation>& poses,
                                             const StereoRefinementOptions& options = {});

}  // namespace cylscan::algo
