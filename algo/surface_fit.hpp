// SPDX-License-Identifier: Apache-2.0
// Metrology fits of the paper's evaluation: least-squares planes (plain and
// robust), spheres (free radius, and fixed radius fitted by its centre) and the
// residual statistics it reports (RMSE, signed mean, STD, regional RMSE).
//
// Residuals are signed geometric distances in mm: for a plane normal·(X − P),
// for a sphere |X − C| − R (positive outside). STD is the population standard
// deviation of the residuals (divisor n), so RMSE² = mean² + STD² exactly, as
// in the paper's sphere table.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "algo/geometry.hpp"

namespace cylscan::algo {

using Points3d = std::vector<Eigen::Vector3d>;

// The finite points of an xyz list (3 floats per point) or of a CV_32FC3 map
// (NaN where invalid).
Points3d pointsFromXyz(std::span<const float> xyz);
Points3d pointsFromXyzMap(const cv::Mat& xyz_map);

struct ResidualStats {
  double rmse = 0.0;
  double mean = 0.0;  // signed
  double std = 0.0;   // population STD about the mean
  std::size_t count = 0;
};
ResidualStats residualStats(std::span<const double> residuals);

// ---------------------------------------------------------------- planes

struct PlaneFit {
  Plane plane;  // point = centroid of the fitted points, unit normal (z ≥ 0 when not parallel)
  double rmse = 0.0;  // RMS of the signed distances of the fitted points
  std::size_t count = 0;
};

// Total least squares: the normal is the eigenvector of the smallest eigenvalue
// of the points' covariance. Needs ≥ 3 non-collinear points (invalid_argument).
PlaneFit fitPlane(std::span<const Eigen::Vector3d> points);

std::vector<double> planeResiduals(std::span<const Eigen::Vector3d> points, const Plane& plane);

struct RobustPlaneOptions {
  double inlier_threshold_mm = 0.5;       // |distance| below this is an inlier
  int max_iterations = 500;               // RANSAC hypotheses at most
  double confidence = 0.9999;             // stop when an all-inlier sample is this likely
  std::size_t max_scored_points = 20000;  // hypotheses are scored on a fixed subsample
  std::uint64_t seed = 0x5eed;
};

struct RobustPlaneFit {
  PlaneFit fit;                       // total least squares on the final inliers
  std::vector<std::uint8_t> inliers;  // 1 per input point
  std::size_t inlier_count = 0;
};

// RANSAC on 3-point hypotheses, then total least squares on the inliers,
// re-selecting inliers with the refitted plane until they no longer change
// (at most a few rounds). Deterministic for a given seed.
RobustPlaneFit fitPlaneRobust(std::span<const Eigen::Vector3d> points,
                              const RobustPlaneOptions& options = {});

// ---------------------------------------------------------------- spheres

struct SphereFit {
  Sphere sphere;
  double rmse = 0.0;  // RMS of |X − C| − R
  std::size_t count = 0;
  int iterations = 0;  // Levenberg–Marquardt iterations used
};

// Free fit: algebraic (linear) initialisation on centred, scaled points, then
// Levenberg–Marquardt on the geometric distances over (centre, radius).
// Needs ≥ 4 non-coplanar points (invalid_argument).
SphereFit fitSphere(std::span<const Eigen::Vector3d> points);

struct FixedRadiusSphereFit {
  Sphere sphere;            // radius = the given one
  ResidualStats residuals;  // of |X − C| − R over all points
  int iterations = 0;
};

// The reference sphere of known radius fitted by its centre only (geometric
// least squares, Levenberg–Marquardt started from the free fit's centre).
FixedRadiusSphereFit fitSphereFixedRadius(std::span<const Eigen::Vector3d> points, double radius);

std::vector<double> sphereResiduals(std::span<const Eigen::Vector3d> points, const Sphere& sphere);

// ---------------------------------------------------------------- regions

struct RegionalRmse {
  double central = 0.0;  // RMSE over the central 30 % of the u-range
  double outer = 0.0;    // RMSE over the left and right 15 % bands together
  std::size_t central_count = 0;
  std::size_t outer_count = 0;
};

// The paper's "Regional RMSE" along the u-axis. residuals[i] belongs to the
// point seen at image column u[i]; the u-range is [u_min, u_max] (e.g. 0 and
// width − 1). Central: |u − mid| ≤ 0.15·range; outer: u ≤ u_min + 0.15·range
// or u ≥ u_max − 0.15·range. An empty region gives NaN.
RegionalRmse regionalRmse(std::span<const double> residuals, std::span<const double> u,
                          double u_min, double u_max);

}  // namespace cylscan::algo
