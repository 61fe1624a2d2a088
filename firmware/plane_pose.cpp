// SPDX-License-Identifier: Apache-2.0
#include "firmware/plane_pose.hpp"

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "algo/numbers.hpp"
#include "algo/surface_fit.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/input_error.hpp"

namespace cylscan::firmware {
namespace {

using algo::kNaNf;
// Below this many stereo points a pose's plane is not trusted.
constexpr std::size_t kMinStereoPoints = 100;

algo::Points3d toPoints(const std::vector<cv::Point3f>& points) {
  algo::Points3d out;
  out.reserve(points.size());
  for (const auto& p : points)
    out.emplace_back(p.x, p.y, p.z);
  return out;
}

cv::Mat inlierMask(cv::Size size, const algo::PhaseStereoResult& stereo,
                   const algo::RobustPlaneFit& plane) {
  cv::Mat mask(size, CV_8U, cv::Scalar(0));
  for (std::size_t i = 0; i < stereo.pixels.size(); ++i)
    mask.at<std::uint8_t>(stereo.pixels[i]) = plane.inliers[i] ? 1 : 0;
  return mask;
}

// Sets the main phase to NaN where the pixel is not used for this pose: a
// pixel with a stereo point must be an inlier; one without needs
// !stereo_pixels_only.
void maskPhase(cv::Mat& phase, const algo::PhaseStereoResult& stereo, const cv::Mat& inliers,
               bool stereo_pixels_only) {
  cv::Mat use(phase.size(), CV_8U, cv::Scalar(stereo_pixels_only ? 0 : 1));
  for (const auto& pixel : stereo.pixels)
    use.at<std::uint8_t>(pixel) = inliers.at<std::uint8_t>(pixel);
  phase.setTo(kNaNf, use == 0);
}

}  // namespace

void PoseOrderReference::follow(const PlanePose& pose) {
  if (!value_ && pose.order_residual.samples > 0) value_ = pose.order_residual.centre_rad;
}

PlanePoseMeasurer::PlanePoseMeasurer(const algo::StereoGeometry& stereo, PlanePoseOptions options)
    : stereo_(stereo), options_(options) {}

PlanePose PlanePoseMeasurer::measure(const formats::CaptureBundleReader& bundle,
                                     std::optional<double> order_reference) const {
  Stopwatch watch;
  PlanePose pose;
  pose.bundle = bundle.dir().string();
  BundlePhaseOptions phase_options;
  phase_options.order_reference_rad = order_reference;
  // Each camera's maps other than the phase used are let go as soon as read:
  // the phase maps of a camera are 31 bytes a pixel, the phase 4.
  cv::Mat phase;
  {
    const BundlePhase main = computeBundlePhase(bundle, "main", phase_options);
    phase = absolutePhase(main.maps, options_.phase);
    pose.main_valid_fraction = main.maps.valid_fraction;
    pose.order_residual = main.maps.order_residual;
  }
  if (pose.order_residual.samples > 0)
    phase_options.order_reference_rad = pose.order_residual.centre_rad;
  cv::Mat phase_aux;
  {
    const BundlePhase aux = computeBundlePhase(bundle, "aux", phase_options);
    phase_aux = absolutePhase(aux.maps, options_.phase);
    pose.aux_valid_fraction = aux.maps.valid_fraction;
  }
  const algo::PhaseStereoResult points = stereo_.reconstruct(phase, phase_aux);
  if (options_.keep_aux_phase) pose.phase_aux = phase_aux;
  phase_aux.release();
  pose.stereo_points = points.points.size();
  if (pose.stereo_points < kMinStereoPoints) {
    throw formats::InputError(bundle.dir(), "only " + std::to_string(pose.stereo_points) +
                                                " stereo points; the plane needs at least " +
                                                std::to_string(kMinStereoPoints));
  }
  algo::RobustPlaneOptions options;
  options.inlier_threshold_mm = options_.plane_tolerance_mm;
  const algo::RobustPlaneFit plane = algo::fitPlaneRobust(toPoints(points.points), options);
  pose.plane = plane.fit.plane;
  pose.plane_inliers = plane.inlier_count;
  pose.plane_rmse_mm = plane.fit.rmse;
  // `phase` is this pose's own map now (its camera's maps are gone): masked in place.
  maskPhase(phase, points, inlierMask(phase.size(), points, plane), options_.stereo_pixels_only);
  pose.phase = std::move(phase);
  pose.ms = watch.elapsedMs();
  return pose;
}

}  // namespace cylscan::firmware
