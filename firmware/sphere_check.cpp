// SPDX-License-Identifier: Apache-2.0
#include "firmware/sphere_check.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "algo/sphere_search.hpp"
#include "algo/surface_fit.hpp"

namespace cylscan::firmware {

SphereCheckResult checkSphere(const formats::PointCloud& cloud, const SphereCheckOptions& options) {
  if (!(options.radius_mm > 0) || !std::isfinite(options.radius_mm))
    throw std::invalid_argument("radius_mm: must be a positive number");
  if (!(options.tolerance_mm > 0) || !std::isfinite(options.tolerance_mm))
    throw std::invalid_argument("tolerance_mm: must be a positive number");
  SphereCheckResult out;
  const algo::Points3d points = algo::pointsFromXyz(cloud.xyz);
  algo::SphereSearchOptions search;
  search.radius_mm = options.radius_mm;
  // The search accepts a sphere whose free radius is within 5 % of the
  // artifact's: a head far out of calibration still finds its sphere and
  // fails the check, rather than finding nothing.
  search.radius_tolerance_mm = 0.05 * options.radius_mm;
  search.inlier_threshold_mm = options.inlier_threshold_mm;
  search.min_inliers = options.min_points;
  search.max_spheres = 1;
  const std::vector<algo::FoundSphere> found = algo::findSpheres(points, search);
  if (found.empty()) {
    out.reason = "no sphere of radius " + std::to_string(options.radius_mm) + " mm with at least " +
                 std::to_string(options.min_points) + " points in the cloud of " +
                 std::to_string(points.size()) + " points";
    return out;
  }
  algo::Points3d on_sphere;
  on_sphere.reserve(found.front().inliers.size());
  for (std::size_t i : found.front().inliers)
    on_sphere.push_back(points[i]);
  const algo::SphereFit fit = algo::fitSphere(on_sphere);
  const std::vector<double> radial = algo::sphereResiduals(on_sphere, fit.sphere);
  // The guideline lets 0.3 % of the points go before the range is taken:
  // those farthest from the sphere.
  std::vector<double> distance(radial.size());
  std::transform(radial.begin(), radial.end(), distance.begin(),
                 [](double r) { return std::abs(r); });
  const auto kept =
      static_cast<std::ptrdiff_t>(std::ceil(0.997 * static_cast<double>(distance.size())) - 1);
  std::nth_element(distance.begin(), distance.begin() + kept, distance.end());
  const double limit = distance[static_cast<std::size_t>(kept)];
  double lo = 0;
  double hi = 0;
  for (double r : radial) {
    if (std::abs(r) > limit) continue;
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  out.found = true;
  out.points = on_sphere.size();
  out.measured_radius_mm = fit.sphere.radius;
  out.rmse_mm = fit.rmse;
  out.probing_form_mm = hi - lo;
  out.probing_size_mm = 2 * (fit.sphere.radius - options.radius_mm);
  for (int k = 0; k < 3; ++k)
    out.centre_mm[k] = fit.sphere.centre[k];
  out.pass = std::abs(fit.sphere.radius - options.radius_mm) <= options.tolerance_mm;
  return out;
}

}  // namespace cylscan::firmware
