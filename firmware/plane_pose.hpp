// SPDX-License-Identifier: Apache-2.0
// One plane pose of the calibration (a capture bundle with main and aux), as
// the quasi-calibration solve and refine-stereo measure it, the paper's way:
// the absolute phase of both cameras, the phase-based stereo points, and a
// robust plane fit of those points, the noise-reduced reference geometry of
// the board.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "algo/geometry.hpp"
#include "algo/phase_stereo.hpp"
#include "firmware/bundle_phase.hpp"
#include "formats/capture_bundle.hpp"

namespace cylscan::firmware {

struct PlanePoseOptions {
  PhaseSource phase = PhaseSource::Fused;
  double plane_tolerance_mm = 0.5;  // stereo points farther from the plane are outliers
  // The main pixels a pose uses: all valid ones (a pixel aux cannot see still
  // has a ray and a plane), or only those with a stereo point on the plane.
  bool stereo_pixels_only = false;
  bool keep_aux_phase = false;
};

struct PlanePose {
  std::string bundle;
  algo::Plane plane;
  cv::Mat phase;      // main, CV_32F, NaN where the pixel is not used
  cv::Mat phase_aux;  // aux, CV_32F (only with keep_aux_phase)
  std::size_t stereo_points = 0;
  std::size_t plane_inliers = 0;
  double plane_rmse_mm = 0;
  double main_valid_fraction = 0;
  double aux_valid_fraction = 0;
  algo::OrderResidual order_residual;  // main's
  std::size_t target_pixels = 0;
  double ms = 0;
};

// The centre a series of poses numbers its orders about: the first pose's
// whose centre was measured.
class PoseOrderReference {
 public:
  std::optional<double> value() const { return value_; }
  void follow(const PlanePose& pose);

 private:
  std::optional<double> value_;
};

class PlanePoseMeasurer {
 public:
  PlanePoseMeasurer(const algo::StereoGeometry& stereo, PlanePoseOptions options);

  // InputError naming the bundle when it yields too few stereo points for a plane.
  // Main's orders are numbered about `order_reference` (the earlier poses'
  // centre: every pose of a calibration numbers them alike), aux's about main's
  // centre (both see the same projector, and stereo matches equal phases).
  PlanePose measure(const formats::CaptureBundleReader& bundle,
                    std::optional<double> order_reference = std::nullopt) const;

 private:
  algo::PhaseStereo stereo_;
  PlanePoseOptions options_;
};

}  // namespace cylscan::firmware
