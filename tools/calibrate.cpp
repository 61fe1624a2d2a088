// SPDX-License-Identifier: Apache-2.0
// cylscan calibrate: the quasi-calibration (paper Eq. 10) from plane poses,
// each a capture bundle with the cameras main and aux (docs/formats.md,
// command line); the solve is firmware/quasi_solve.hpp's.
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "algo/quasi_calibration.hpp"
#include "firmware/quasi_solve.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/atomic_file.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {
namespace {

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

nlohmann::json summaryJson(const CalibrateRequest& request,
                           const firmware::QuasiSolveResult& result,
                           const nlohmann::json& timings) {
  nlohmann::json pose_list = nlohmann::json::array();
  for (const auto& pose : result.poses)
    pose_list.push_back(firmware::quasiPoseJson(pose));
  const algo::QuasiCalibration& calib = result.calibration;
  const double area = calib.size().area();
  return {{"width", calib.size().width},
          {"height", calib.size().height},
          {"phase", request.phase},
          {"poses", pose_list},
          {"pooled_rmse_mm", result.pooled_rmse_mm},
          {"pooled_distance_rmse_mm", result.pooled_distance_rmse_mm},
          {"sensitivity_mm_per_rad", result.sensitivity_mm_per_rad},
          {"order_centre_rad", calib.info().order_centre_rad},
          {"residual_pixels", result.residual_pixels},
          {"valid_pixels", calib.validCount()},
          {"valid_fraction", static_cast<double>(calib.validCount()) / area},
          {"timings_ms", timings},
          {"out", request.out}};
}

void printSummary(const firmware::QuasiSolveResult& result) {
  const algo::QuasiCalibration& calib = result.calibration;
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "calibrate: " << result.poses.size() << " poses, " << calib.validCount() << " of "
            << calib.size().area() << " pixels calibrated\n";
  for (const auto& pose : result.poses) {
    std::cout << "  " << pose.bundle << ": RMSE " << pose.rmse_mm << " mm (plane fit of "
              << pose.plane_inliers << " stereo points: RMSE " << pose.plane_rmse_mm << " mm)\n";
  }
  std::cout << "  pooled RMSE " << result.pooled_rmse_mm << " mm, S_eff "
            << result.sensitivity_mm_per_rad << " mm/rad\n";
}

// The solve, its errors in the command's words.
firmware::QuasiSolveResult solve(const CalibrateRequest& request) {
  firmware::QuasiSolveOptions options;
  options.phase = parsePhaseSource(request.phase);
  options.min_poses = request.min_poses;
  options.plane_tolerance_mm = request.plane_tolerance_mm;
  options.stereo_pixels_only = request.stereo_pixels_only;
  options.stereo_file = request.stereo;
  try {
    // Counted before the stereo file is read: the request itself is short.
    firmware::requireEnoughPoses(request.bundles.size(), request.min_poses);
    const formats::StereoCalibration stereo = formats::readStereoCalibration(request.stereo);
    return firmware::solveQuasiCalibration(
        stereo, std::vector<std::filesystem::path>(request.bundles.begin(), request.bundles.end()),
        options);
  } catch (const firmware::TooFewPoses& e) {
    throw std::invalid_argument(std::string("calibrate: ") + e.what());
  } catch (const firmware::NoPixelCalibrated& e) {
    throw std::runtime_error(std::string("calibrate: ") + e.what() + "; nothing written");
  }
}

void runCalibrate(const CalibrateRequest& request) {
  firmware::Stopwatch total;
  const firmware::QuasiSolveResult result = solve(request);
  firmware::Stopwatch watch;
  formats::writeFileAtomically(request.out, result.calibration.serialize());
  const nlohmann::json timings = {{"measure", result.timings.measure_ms},
                                  {"fit", result.timings.fit_ms},
                                  {"residuals", result.timings.residuals_ms},
                                  {"write", watch.lapMs()},
                                  {"total", total.elapsedMs()}};
  if (request.json) {
    std::cout << summaryJson(request, result, timings).dump() << "\n";
  } else {
    printSummary(result);
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
