// SPDX-License-Identifier: Apache-2.0
// cylscan calibrate-stereo: the stereo calibration file of the main and aux
// cameras from a checkerboard set (both in docs/formats.md). The corners and
// the solve are firmware/checkerboard_corners.hpp's and firmware/stereo_solve.hpp's.
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "firmware/checkerboard_corners.hpp"
#include "firmware/stereo_solve.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/checkerboard_set.hpp"
#include "formats/input_error.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {
namespace {

struct CalibrateStereoRequest {
  std::string board;
  std::string out;
  int min_pairs = 6;
  std::string model = "k1k2p1p2k3";
  bool refine_jointly = false;
  bool json = false;
};

nlohmann::json cameraJson(const firmware::StereoCameraResult& fit) {
  const cv::Matx33d& k = fit.camera_matrix;
  const firmware::IntrinsicSigmas& s = fit.sigma;
  return {{"rms_px", fit.rms_px},
          {"fx", k(0, 0)},
          {"fy", k(1, 1)},
          {"cx", k(0, 2)},
          {"cy", k(1, 2)},
          {"dist_coeffs", std::vector<double>(fit.dist_coeffs.val, fit.dist_coeffs.val + 5)},
          {"sigma_fx_fy_cx_cy_k1_k2_p1_p2_k3",
           {s.fx, s.fy, s.cx, s.cy, s.dist_coeffs[0], s.dist_coeffs[1], s.dist_coeffs[2],
            s.dist_coeffs[3], s.dist_coeffs[4]}}};
}

nlohmann::json summaryJson(const CalibrateStereoRequest& request,
                           const firmware::StereoSolveResult& fit, double total_ms) {
  nlohmann::json rejections = nlohmann::json::array();
  for (const auto& r : fit.rejected)
    rejections.push_back({{"id", r.id}, {"reason", r.reason}});
  nlohmann::json views = nlohmann::json::array();
  for (const auto& view : fit.views) {
    views.push_back({{"id", view.id},
                     {"main_rms_px", view.main_rms_px},
                     {"aux_rms_px", view.aux_rms_px},
                     {"stereo_rms_px", view.stereo_rms_px}});
  }
  const cv::Vec3d& t = fit.calibration.T;
  return {{"width", fit.image_size.width},
          {"height", fit.image_size.height},
          {"pairs", fit.pair_count},
          {"pairs_used", fit.views.size()},
          {"rejected", rejections},
          {"main", cameraJson(fit.main)},
          {"aux", cameraJson(fit.aux)},
          {"stereo_rms_px", fit.stereo_rms_px},
          {"model", request.model},
          {"refinement", request.refine_jointly ? "joint" : "fixed-intrinsics"},
          {"baseline_mm", fit.baseline_mm},
          {"T_mm", {t[0], t[1], t[2]}},
          {"views", views},
          {"timings_ms", {{"total", total_ms}}},
          {"out", request.out}};
}

void printSummary(const firmware::StereoSolveResult& fit) {
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "calibrate-stereo: " << fit.views.size() << " of " << fit.pair_count
            << " pairs used\n";
  for (const auto& [name, cam] : {std::pair{"main", &fit.main}, std::pair{"aux", &fit.aux}}) {
    const cv::Matx33d& k = cam->camera_matrix;
    std::cout << "  " << name << ": RMS " << cam->rms_px << " px, fx " << k(0, 0) << " fy "
              << k(1, 1) << " cx " << k(0, 2) << " cy " << k(1, 2) << "\n";
  }
  std::cout << "  stereo: RMS " << fit.stereo_rms_px << " px, baseline " << fit.baseline_mm
            << " mm\n";
  for (const auto& r : fit.rejected)
    std::cout << "  rejected " << r.id << ": " << r.reason << "\n";
}

// The solve, its errors in the command's words.
firmware::StereoSolveResult solve(const CalibrateStereoRequest& request) {
  const formats::CheckerboardSet set = formats::readCheckerboardSet(request.board);
  firmware::StereoCorners corners = firmware::detectStereoCorners(set);
  firmware::StereoSolveOptions options;
  options.min_pairs = request.min_pairs;
  options.model = request.model;
  options.refine_jointly = request.refine_jointly;
  try {
    return firmware::solveStereo(set.board, std::move(corners), options);
  } catch (const firmware::BoardNotFound& e) {
    throw formats::InputError(std::filesystem::path(request.board) / "checkerboard.json", e.what());
  } catch (const firmware::TooFewPairs& e) {
    throw std::runtime_error(
        "calibrate-stereo: only " + std::to_string(e.usable()) + " usable checkerboard pairs" +
        (e.afterOutliers() ? " after dropping the reprojection outliers" : "") + ", at least " +
        std::to_string(e.needed()) + " (--min-pairs) are needed; nothing written" + e.reasons());
  }
}

void runCalibrateStereo(const CalibrateStereoRequest& request) {
  firmware::Stopwatch total;
  const firmware::StereoSolveResult fit = solve(request);
  formats::writeStereoCalibration(request.out, fit.calibration);
  if (request.json) {
    std::cout << summaryJson(request, fit, total.elapsedMs()).dump() << "\n";
  } else {
    printSummary(fit);
  }
}

}  // namespace

void addCalibrateStereoCommand(CLI::App& app) {
  auto request = std::make_shared<CalibrateStereoRequest>();
  CLI::App* cmd = app.add_subcommand("calibrate-stereo",
                                     "stereo calibration of main and aux from a checkerboard set");
  cmd->add_option("--board", request->board, "checkerboard set directory (docs/formats.md)")
      ->required();
  cmd->add_option("--out", request->out, "stereo calibration file to write (docs/formats.md)")
      ->required();
  cmd->add_option("--min-pairs", request->min_pairs,
                  "usable pairs needed, counted after dropping reprojection outliers (default 6)")
      ->check(CLI::Range(3, 10000));
  cmd->add_option("--model", request->model,
                  "distortion coefficients estimated: k1k2p1p2k3 (default), k1k2p1p2 or k1k2")
      ->check(CLI::IsMember({"k1k2p1p2k3", "k1k2p1p2", "k1k2"}));
  cmd->add_flag("--refine-jointly", request->refine_jointly,
                "refine the intrinsics together with R and T instead of fixing them");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runCalibrateStereo(*request); });
}

}  // namespace cylscan::tools
