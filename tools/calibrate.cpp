// SPDX-License-Identifier: Apache-2.0
// cylscan calibrate: the quasi-calibration (paper Eq. 10) from plane poses,
// each a capture bundle with the cameras main and aux (docs/formats.md,
// command line).
//
// For each pose: the absolute phase of main and aux (the phase engine), the
// phase-based stereo points (PhaseStereo, main camera frame), a robust plane
// fit of those points (the noise-reduced reference geometry of the board),
// and the target XYZ of every valid main pixel = its viewing ray (intrinsics
// and distortion) ∩ the fitted plane. A main pixel counts when its phase is
// valid and its stereo point, if it has one, lies within the plane tolerance
// (a pixel aux cannot see still has a ray and a plane; with
// --stereo-pixels-only it must have a stereo inlier).
//
// Memory: poses are processed one at a time; the fitter holds O(pixels) sums.
// For the residual pass (Eq. 12) each pose keeps only its masked phase map
// (4 bytes a pixel, ~3.2 MB at 1000×800) and its plane: the targets are
// recomputed from the rays, so no bundle is read twice.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "algo/phase_stereo.hpp"
#include "algo/quasi_calibration.hpp"
#include "algo/ray_plane.hpp"
#include "algo/surface_fit.hpp"
#include "firmware/scan_output.hpp"
#include "formats/atomic_file.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/input_error.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/bundle_phase.hpp"
#include "tools/commands.hpp"
#include "tools/plane_pose.hpp"
#include "tools/scene_truth.hpp"
#include "tools/stereo_geometry.hpp"
#include "tools/stopwatch.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;

struct CalibrateRequest {
  std::string stereo;
  std::string out;
  std::vector<std::string> bundles;
  std::string phase = "fused";
  int min_poses = 6;
  double plane_tolerance_mm = 0.5;
  bool stereo_pixels_only = false;
  bool json = false;
};

std::vector<formats::CaptureBundleReader> openBundles(const CalibrateRequest& request) {
  std::vector<formats::CaptureBundleReader> bundles;
  for (const auto& dir : request.bundles) {
    bundles.emplace_back(dir);
    requireCamera(bundles.back(), "main");
    requireCamera(bundles.back(), "aux");
  }
  return bundles;
}

void requireSizes(const std::vector<formats::CaptureBundleReader>& bundles,
                  const formats::StereoCalibration& stereo, const fs::path& stereo_file) {
  for (const auto& bundle : bundles) {
    for (const char* camera : {"main", "aux"}) {
      requireStereoImageSize(stereo_file, stereo, bundle.frameSize(camera), bundle.dir() / camera);
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

nlohmann::json summaryJson(const CalibrateRequest& request, const std::vector<PlanePose>& poses,
                           const algo::QuasiCalibration& calib,
                           const algo::CalibrationResiduals& residuals,
                           const nlohmann::json& timings) {
  nlohmann::json pose_list = nlohmann::json::array();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const PlanePose& p = poses[i];
    const algo::PoseResidual& r = residuals.poses[i];
    pose_list.push_back(
        {{"bundle", p.bundle},
         {"rmse_mm", r.depth_rmse_mm},
         {"distance_rmse_mm", r.distance_rmse_mm},
         {"pixels", r.pixel_count},
         {"target_pixels", p.target_pixels},
         {"stereo_points", p.stereo_points},
         {"plane_inliers", p.plane_inliers},
         {"plane_fit_rmse_mm", p.plane_rmse_mm},
         {"plane", {{"point", vec3Json(p.plane.point)}, {"normal", vec3Json(p.plane.normal)}}},
         {"main_valid_fraction", p.main_valid_fraction},
         {"aux_valid_fraction", p.aux_valid_fraction},
         {"order_residual", firmware::orderResidualJson(p.order_residual)},
         {"ms", p.ms}});
  }
  const double area = calib.size().area();
  return {{"width", calib.size().width},
          {"height", calib.size().height},
          {"phase", request.phase},
          {"poses", pose_list},
          {"pooled_rmse_mm", residuals.pooled_depth_rmse_mm},
          {"pooled_distance_rmse_mm", residuals.pooled_distance_rmse_mm},
          {"sensitivity_mm_per_rad", residuals.sensitivity_mm_per_rad},
          {"order_centre_rad", calib.info().order_centre_rad},
          {"residual_pixels", residuals.pixel_count},
          {"valid_pixels", calib.validCount()},
          {"valid_fraction", static_cast<double>(calib.validCount()) / area},
          {"timings_ms", timings},
          {"out", request.out}};
}

void printSummary(const std::vector<PlanePose>& poses, const algo::QuasiCalibration& calib,
                  const algo::CalibrationResiduals& residuals) {
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "calibrate: " << poses.size() << " poses, " << calib.validCount() << " of "
            << calib.size().area() << " pixels calibrated\n";
  for (std::size_t i = 0; i < poses.size(); ++i) {
    std::cout << "  " << poses[i].bundle << ": RMSE " << residuals.poses[i].depth_rmse_mm
              << " mm (plane fit of " << poses[i].plane_inliers << " stereo points: RMSE "
              << poses[i].plane_rmse_mm << " mm)\n";
  }
  std::cout << "  pooled RMSE " << residuals.pooled_depth_rmse_mm << " mm, S_eff "
            << residuals.sensitivity_mm_per_rad << " mm/rad\n";
}

void runCalibrate(const CalibrateRequest& request) {
  Stopwatch total;
  const PhaseSource choice = parsePhaseSource(request.phase);
  if (static_cast<int>(request.bundles.size()) < request.min_poses) {
    throw std::invalid_argument("calibrate: " + std::to_string(request.bundles.size()) +
                                " plane poses given, at least " +
                                std::to_string(request.min_poses) + " are needed");
  }
  const formats::StereoCalibration stereo = formats::readStereoCalibration(request.stereo);
  const std::vector<formats::CaptureBundleReader> bundles = openBundles(request);
  requireSizes(bundles, stereo, request.stereo);

  const algo::RayMap rays(mainCamera(stereo));
  PlanePoseOptions pose_options;
  pose_options.phase = choice;
  pose_options.plane_tolerance_mm = request.plane_tolerance_mm;
  pose_options.stereo_pixels_only = request.stereo_pixels_only;
  const PlanePoseMeasurer measurer(toStereoGeometry(stereo), pose_options);
  algo::QuasiCalibrationOptions options;
  options.min_poses = request.min_poses;
  options.phase_source = choice == PhaseSource::High ? PhaseSource::High : PhaseSource::Fused;
  algo::QuasiCalibrationFitter fitter(rays.size(), options);
  std::vector<PlanePose> poses;
  Stopwatch watch;
  PoseOrderReference order_reference;
  for (const auto& bundle : bundles) {
    PlanePose pose = measurer.measure(bundle, order_reference.value());
    order_reference.follow(pose);
    const cv::Mat target = algo::intersectRaysWithPlane(rays, pose.plane);
    fitter.addPose(pose.phase, target);
    pose.target_pixels = finiteCount(pose.phase);
    poses.push_back(std::move(pose));
  }
  const double measure_ms = watch.lapMs();
  algo::QuasiCalibration calib = fitter.fit();
  if (calib.validCount() == 0) {
    throw std::runtime_error("calibrate: no pixel was seen in " +
                             std::to_string(request.min_poses) + " poses; nothing written");
  }
  const double fit_ms = watch.lapMs();
  algo::QuasiCalibrationResiduals pass(calib);
  for (const auto& pose : poses) {
    pass.addPose(pose.phase, algo::intersectRaysWithPlane(rays, pose.plane));
  }
  const algo::CalibrationResiduals residuals = pass.result();
  calib.setResidualSummary(static_cast<float>(residuals.pooled_depth_rmse_mm),
                           static_cast<float>(residuals.sensitivity_mm_per_rad));
  if (const std::optional<double> centre = order_reference.value())
    calib.setOrderResidual(static_cast<float>(*centre), static_cast<float>(medianSpread(poses)));
  const double residual_ms = watch.lapMs();
  formats::writeFileAtomically(request.out, calib.serialize());
  const nlohmann::json timings = {{"measure", measure_ms},
                                  {"fit", fit_ms},
                                  {"residuals", residual_ms},
                                  {"write", watch.lapMs()},
                                  {"total", total.elapsedMs()}};
  if (request.json) {
    std::cout << summaryJson(request, poses, calib, residuals, timings).dump() << "\n";
  } else {
    printSummary(poses, calib, residuals);
  }
}

}  // namespace

void addCalibrateCommand(CLI::App& app) {
  auto request = std::make_shared<CalibrateRequest>();
  CLI::App* cmd =
      app.add_subcommand("calibrate", "quasi-calibration from plane poses (bundles with main+aux)");
  cmd->add_option("bundles", request->bundles, "calibration bundles, one per plane pose")
      ->required();
  cmd->add_option("--stereo", request->stereo, "stereo calibration file (docs/formats.md)")
      ->required();
  cmd->add_option("--out", request->out, "calibration file to write")->required();
  cmd->add_option("--phase", request->phase, "absolute phase to model: fused (default) or high")
      ->check(CLI::IsMember({"high", "fused"}));
  cmd->add_option("--min-poses", request->min_poses,
                  "poses a pixel must be seen in, and poses needed (default 6)")
      ->check(CLI::Range(6, 1000));
  cmd->add_option("--plane-tolerance", request->plane_tolerance_mm,
                  "mm: stereo points farther from the pose's plane are outliers (default 0.5)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--stereo-pixels-only", request->stereo_pixels_only,
                "use only main pixels with a stereo point on the plane");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runCalibrate(*request); });
}

}  // namespace cylscan::tools
