// SPDX-License-Identifier: Apache-2.0
#include "firmware/quasi_solve.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "algo/ray_plane.hpp"
#include "firmware/bundle_phase.hpp"
#include "firmware/plane_pose.hpp"
#include "firmware/scan_output.hpp"
#include "firmware/stereo_geometry.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/input_error.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;

// The progress of the solve's steps: measuring the poses (their phase, read
// from the frames, is nearly all of the time), then the fit, then the
// residual pass.
constexpr double kMeasureEnd = 0.9;
constexpr double kFitEnd = 0.96;

std::vector<formats::CaptureBundleReader> openBundles(const std::vector<fs::path>& dirs) {
  std::vector<formats::CaptureBundleReader> bundles;
  bundles.reserve(dirs.size());
  for (const auto& dir : dirs) {
    bundles.emplace_back(dir);
    requireCamera(bundles.back(), "main");
    requireCamera(bundles.back(), "aux");
  }
  return bundles;
}

void requireSizes(const std::vector<formats::CaptureBundleReader>& bundles,
                  const formats::StereoCalibration& stereo, const fs::path& stereo_file) {
  const cv::Size calibrated(stereo.image_width, stereo.image_height);
  for (const auto& bundle : bundles) {
    for (const char* camera : {"main", "aux"}) {
      const cv::Size size = bundle.frameSize(camera);
      const fs::path images = bundle.dir() / camera;
      if (!stereo_file.empty()) {
        requireStereoImageSize(stereo_file, stereo, size, images);
      } else if (size != calibrated) {
        throw formats::InputError(
            images, "has " + std::to_string(size.width) + "x" + std::to_string(size.height) +
                        " images, the stereo calibration is for " +
                        std::to_string(calibrated.width) + "x" + std::to_string(calibrated.height));
      }
    }
  }
}

std::size_t finiteCount(const cv::Mat& phase) {
  std::size_t count = 0;
  for (int v = 0; v < phase.rows; ++v) {
    const float* row = phase.ptr<float>(v);
    for (int u = 0; u < phase.cols; ++u)
      count += std::isfinite(row[u]) ? 1 : 0;
  }
  return count;
}

// The poses' median order-residual spread, over those that measured one.
double medianSpread(const std::vector<PlanePose>& poses) {
  std::vector<double> spreads;
  for (const PlanePose& pose : poses)
    if (pose.order_residual.samples > 0) spreads.push_back(pose.order_residual.spread_rad);
  if (spreads.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto middle = spreads.begin() + static_cast<std::ptrdiff_t>(spreads.size() / 2);
  std::nth_element(spreads.begin(), middle, spreads.end());
  return *middle;
}

QuasiPoseResult poseResult(const PlanePose& pose, const algo::PoseResidual& residual) {
  QuasiPoseResult out;
  out.bundle = pose.bundle;
  out.rmse_mm = residual.depth_rmse_mm;
  out.distance_rmse_mm = residual.distance_rmse_mm;
  out.pixels = residual.pixel_count;
  out.target_pixels = pose.target_pixels;
  out.stereo_points = pose.stereo_points;
  out.plane_inliers = pose.plane_inliers;
  out.plane_rmse_mm = pose.plane_rmse_mm;
  out.plane = pose.plane;
  out.main_valid_fraction = pose.main_valid_fraction;
  out.aux_valid_fraction = pose.aux_valid_fraction;
  out.order_residual = pose.order_residual;
  out.ms = pose.ms;
  return out;
}

// Measures the poses in order, each numbering its orders about the first
// measured centre; `order_reference` ends with that centre.
std::vector<PlanePose> measurePoses(const formats::StereoCalibration& stereo,
                                    const std::vector<formats::CaptureBundleReader>& bundles,
                                    const QuasiSolveOptions& options,
                                    PoseOrderReference& order_reference, ProgressSpan& report) {
  PlanePoseOptions pose_options;
  pose_options.phase = options.phase;
  pose_options.plane_tolerance_mm = options.plane_tolerance_mm;
  pose_options.stereo_pixels_only = options.stereo_pixels_only;
  const PlanePoseMeasurer measurer(toStereoGeometry(stereo), pose_options);
  // The poses' masked phase maps live until the residual pass: they are
  // copied into one block allocated before any pose is measured, as each
  // pose's own map, left among the maps the pose lets go, would scatter the
  // heap (12 MB more peak memory at 1000×800 with 14 poses).
  const cv::Size size(stereo.image_width, stereo.image_height);
  cv::Mat kept(size.height * static_cast<int>(bundles.size()), size.width, CV_32F);
  std::vector<PlanePose> poses;
  poses.reserve(bundles.size());
  for (const auto& bundle : bundles) {
    poses.push_back(measurer.measure(bundle, order_reference.value()));
    order_reference.follow(poses.back());
    const int first = size.height * static_cast<int>(poses.size() - 1);
    cv::Mat phase = kept.rowRange(first, first + size.height);
    poses.back().phase.copyTo(phase);
    poses.back().phase = phase;
    report(kMeasureEnd * static_cast<double>(poses.size()) / static_cast<double>(bundles.size()));
  }
  return poses;
}

// The fit of every pixel's polynomials over the measured poses.
//
// Memory: the fitter's sums (184 bytes a pixel, 147 MB at 1000×800) are the
// largest thing the solve holds, so they exist only from here to the fit,
// after the poses were measured; the rays (24 bytes a pixel) are let go
// before the fit makes the calibration (57 bytes a pixel), and made again for
// the residual pass (~80 ms at 1000×800, a sixth of one pose's measurement).
algo::QuasiCalibration fitPoses(const algo::PinholeCamera& camera, std::vector<PlanePose>& poses,
                                const QuasiSolveOptions& options) {
  std::optional<algo::RayMap> rays(std::in_place, camera);
  algo::QuasiCalibrationOptions fit_options;
  fit_options.min_poses = options.min_poses;
  fit_options.phase_source =
      options.phase == PhaseSource::High ? PhaseSource::High : PhaseSource::Fused;
  algo::QuasiCalibrationFitter fitter(rays->size(), fit_options);
  for (PlanePose& pose : poses) {
    fitter.addPose(pose.phase, algo::intersectRaysWithPlane(*rays, pose.plane));
    pose.target_pixels = finiteCount(pose.phase);
  }
  rays.reset();
  return fitter.fit();
}

}  // namespace

TooFewPoses::TooFewPoses(std::size_t given, int needed)
    : std::invalid_argument(std::to_string(given) + " plane poses given, at least " +
                            std::to_string(needed) + " are needed"),
      given_(given),
      needed_(needed) {}

NoPixelCalibrated::NoPixelCalibrated(int min_poses)
    : std::runtime_error("no pixel was seen in " + std::to_string(min_poses) + " poses") {}

void requireEnoughPoses(std::size_t given, int min_poses) {
  if (given < static_cast<std::size_t>(std::max(min_poses, 0))) throw TooFewPoses(given, min_poses);
}

QuasiSolveResult solveQuasiCalibration(const formats::StereoCalibration& stereo,
                                       const std::vector<fs::path>& bundle_dirs,
                                       const QuasiSolveOptions& options,
                                       const SolveProgress& progress) {
  ProgressSpan report(progress, 0.0, 1.0);
  report(0.0);
  requireEnoughPoses(bundle_dirs.size(), options.min_poses);
  const std::vector<formats::CaptureBundleReader> bundles = openBundles(bundle_dirs);
  requireSizes(bundles, stereo, options.stereo_file);

  QuasiSolveTimings timings;
  Stopwatch watch;
  PoseOrderReference order_reference;
  std::vector<PlanePose> poses = measurePoses(stereo, bundles, options, order_reference, report);
  timings.measure_ms = watch.lapMs();

  const algo::PinholeCamera camera = mainCamera(stereo);
  algo::QuasiCalibration calib = fitPoses(camera, poses, options);
  if (calib.validCount() == 0) throw NoPixelCalibrated(options.min_poses);
  timings.fit_ms = watch.lapMs();
  report(kFitEnd);

  const algo::RayMap rays(camera);
  algo::QuasiCalibrationResiduals pass(calib);
  for (PlanePose& pose : poses) {
    pass.addPose(pose.phase, algo::intersectRaysWithPlane(rays, pose.plane));
    pose.phase.release();  // the result keeps the figures only
  }
  const algo::CalibrationResiduals residuals = pass.result();
  calib.setResidualSummary(static_cast<float>(residuals.pooled_depth_rmse_mm),
                           static_cast<float>(residuals.sensitivity_mm_per_rad));
  if (const std::optional<double> centre = order_reference.value())
    calib.setOrderResidual(static_cast<float>(*centre), static_cast<float>(medianSpread(poses)));
  timings.residuals_ms = watch.lapMs();

  std::vector<QuasiPoseResult> pose_results;
  pose_results.reserve(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i)
    pose_results.push_back(poseResult(poses[i], residuals.poses[i]));
  QuasiSolveResult result{std::move(calib),
                          std::move(pose_results),
                          residuals.pooled_depth_rmse_mm,
                          residuals.pooled_distance_rmse_mm,
                          residuals.sensitivity_mm_per_rad,
                          residuals.pixel_count,
                          timings};
  report(1.0);
  return result;
}

nlohmann::json quasiPoseJson(const QuasiPoseResult& pose) {
  const auto vec3 = [](const Eigen::Vector3d& v) { return nlohmann::json{v.x(), v.y(), v.z()}; };
  return {{"bundle", pose.bundle},
          {"rmse_mm", pose.rmse_mm},
          {"distance_rmse_mm", pose.distance_rmse_mm},
          {"pixels", pose.pixels},
          {"target_pixels", pose.target_pixels},
          {"stereo_points", pose.stereo_points},
          {"plane_inliers", pose.plane_inliers},
          {"plane_fit_rmse_mm", pose.plane_rmse_mm},
          {"plane", {{"point", vec3(pose.plane.point)}, {"normal", vec3(pose.plane.normal)}}},
          {"main_valid_fraction", pose.main_valid_fraction},
          {"aux_valid_fraction", pose.aux_valid_fraction},
          {"order_residual", orderResidualJson(pose.order_residual)},
          {"ms", pose.ms}};
}

}  // namespace cylscan::firmware
