// SPDX-License-Identifier: Apache-2.0
// Finding the spheres of a target in a point cloud: sequential RANSAC on
// 4-point sphere hypotheses (seed point plus neighbours), each winner refined
// by the free geometric fit of surface_fit on its inliers and removed before
// the next search. Used by `cylscan calibrate-head` (the turntable target).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "algo/surface_fit.hpp"

namespace cylscan::algo {

struct SphereSearchOptions {
  double radius_mm = 0;            // the spheres' known radius; 0 = any radius
  double radius_tolerance_mm = 1;  // a found sphere's free radius within this of radius_mm
  double min_radius_mm = 5;        // with radius_mm = 0: the radii accepted
  double max_radius_mm = 200;
  double inlier_threshold_mm = 0.4;  // |distance to the sphere| of an inlier
  std::size_t min_inliers = 200;     // a sphere needs at least this many points
  std::size_t max_spheres = 8;
  int iterations = 1500;                 // hypotheses per sphere
  std::size_t max_scored_points = 6000;  // hypotheses are scored on a subsample
  std::uint64_t seed = 0x5eed;
};

struct FoundSphere {
  SphereFit fit;                     // free fit on the inliers
  std::vector<std::size_t> inliers;  // indices into the input points
};

// The spheres found, most points first; empty when none qualifies.
// Deterministic for a given seed.
std::vector<FoundSphere> findSpheres(std::span<const Eigen::Vector3d> points,
                                     const SphereSearchOptions& options = {});

}  // namespace cylscan::algo
