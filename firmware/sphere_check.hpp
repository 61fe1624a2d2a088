// SPDX-License-Identifier: Apache-2.0
// A head checked against a known artifact: a reference sphere of calibrated
// radius, scanned like any object. The sphere is found in the cloud (RANSAC
// for the known radius, so a backdrop or a holder is left out), fitted
// freely, and judged by its radius error against a tolerance. The figures
// of VDI/VDE 2634 part 2 that one sphere gives are reported with it:
//   - probing error form PF: the range of the radial distances of the
//     sphere's points from the free fit (max − min), the 0.3 % farthest
//     points left out as the guideline allows, and
//   - probing error size PS: the fitted diameter minus the calibrated one.
// The guideline measures PF and PS over several positions of the sphere in
// the working volume; one scan gives one position's values.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "formats/point_cloud.hpp"

namespace cylscan::firmware {

struct SphereCheckOptions {
  double radius_mm = 0;     // the artifact's calibrated radius (> 0)
  double tolerance_mm = 0;  // |measured − calibrated radius| allowed (> 0)
  // Points this far from the sphere found by RANSAC take part in the fit:
  // wide enough for a head's noise, narrow enough to leave out a backdrop.
  double inlier_threshold_mm = 0.5;
  std::size_t min_points = 500;  // fewer on the sphere: no check
};

struct SphereCheckResult {
  bool found = false;      // a sphere of about that radius was in the cloud
  std::string reason;      // why not, when not found
  std::size_t points = 0;  // on the sphere
  double measured_radius_mm = 0;
  double rmse_mm = 0;  // of the radial distances from the free fit
  double probing_form_mm = 0;
  double probing_size_mm = 0;
  double centre_mm[3] = {0, 0, 0};
  bool pass = false;  // found, and the radius within the tolerance
};

// std::invalid_argument for a radius or tolerance that is not positive.
SphereCheckResult checkSphere(const formats::PointCloud& cloud, const SphereCheckOptions& options);

}  // namespace cylscan::firmware
