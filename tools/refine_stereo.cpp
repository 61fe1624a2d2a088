// SPDX-License-Identifier: Apache-2.0
// cylscan refine-stereo: refines a checkerboard stereo calibration with the
// phase of the plane poses (algo/stereo_refinement.hpp): the checkerboard
// corners fix the scale, the dense equal-phase correspondences on known planes
// fix the rest. Writes a stereo calibration file (docs/formats.md) for
// `calibrate`.
//
// With --truth (the virtual head's stereo_truth.yaml) it also reports how far
// the initial and the refined calibrations are from the truth.
#include <cmath>
#include <iomanip>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "algo/stereo_refinement.hpp"
#include "firmware/bundle_phase.hpp"
#include "firmware/checkerboard_corners.hpp"
#include "firmware/plane_pose.hpp"
#include "firmware/stereo_geometry.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/checkerboard_set.hpp"
#include "formats/input_error.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {
namespace {

using nlohmann::json;

struct RefineStereoRequest {
  std::string stereo;
  std::string board;
  std::string out;
  std::string truth;
  std::vector<std::string> bundles;
  std::string model = "k1k2p1p2k3";
  std::string phase = "fused";
  int samples = 3000;
  int min_poses = 3;
  bool json = false;
};

algo::CheckerboardObservations observeBoards(const RefineStereoRequest& request, cv::Size size,
                                             std::vector<firmware::Rejection>& rejected) {
  const formats::CheckerboardSet set = formats::readCheckerboardSet(request.board);
  firmware::StereoCorners corners = firmware::detectStereoCorners(set);
  rejected = std::move(corners.rejected);
  const cv::Size found = corners.image_size;
  if (!found.empty() && found != size) {
    throw formats::InputError(
        request.board, "images are " + std::to_string(found.width) + "x" +
                           std::to_string(found.height) + ", the stereo calibration is for " +
                           std::to_string(size.width) + "x" + std::to_string(size.height));
  }
  algo::CheckerboardObservations boards;
  boards.object = firmware::boardPoints(set.board);
  for (const auto& pair : corners.pairs)
    boards.views.push_back({pair.main, pair.aux});
  return boards;
}

// How far `geometry` is from `truth`: relative focal errors, principal point,
// the angle of the relative rotation and the translation error.
json errorsAgainst(const algo::StereoGeometry& geometry, const algo::StereoGeometry& truth) {
  auto camera = [](const algo::PinholeCamera& c, const algo::PinholeCamera& t) {
    const cv::Matx33d& k = c.camera_matrix;
    const cv::Matx33d& kt = t.camera_matrix;
    return json{{"fx_rel", k(0, 0) / kt(0, 0) - 1.0},
                {"fy_rel", k(1, 1) / kt(1, 1) - 1.0},
                {"cx_px", k(0, 2) - kt(0, 2)},
                {"cy_px", k(1, 2) - kt(1, 2)}};
  };
  cv::Vec3d angle;
  cv::Rodrigues(geometry.rotation * truth.rotation.t(), angle);
  return {{"main", camera(geometry.main, truth.main)},
          {"aux", camera(geometry.aux, truth.aux)},
          {"rotation_deg", cv::norm(angle) * 180.0 / CV_PI},
          {"translation_mm", cv::norm(geometry.translation - truth.translation)},
          {"baseline_rel", cv::norm(geometry.translation) / cv::norm(truth.translation) - 1.0}};
}

json residualJson(const algo::ResidualSummary& s) {
  return {{"board_main_rms_px", s.board_main_rms_px},
          {"board_aux_rms_px", s.board_aux_rms_px},
          {"phase_rms_px", s.phase_rms_px},
          {"phase_samples", s.phase_samples}};
}

json cameraJson(const algo::PinholeCamera& c) {
  const cv::Matx33d& k = c.camera_matrix;
  return {{"fx", k(0, 0)},
          {"fy", k(1, 1)},
          {"cx", k(0, 2)},
          {"cy", k(1, 2)},
          {"dist_coeffs", std::vector<double>(c.dist_coeffs.val, c.dist_coeffs.val + 5)}};
}

void printSummary(const json& s) {
  std::cout << std::fixed << std::setprecision(4);
  const json& b = s.at("before");
  const json& a = s.at("after");
  std::cout << "refine-stereo: " << s.at("boards").get<int>() << " checkerboard views, "
            << s.at("poses").size() << " plane poses, " << s.at("unknowns").get<int>()
            << " unknowns, " << s.at("iterations").get<int>() << " iterations\n";
  std::cout << "  checkerboard RMS: main " << b.at("board_main_rms_px").get<double>() << " -> "
            << a.at("board_main_rms_px").get<double>() << " px, aux "
            << b.at("board_aux_rms_px").get<double>() << " -> "
            << a.at("board_aux_rms_px").get<double>() << " px\n";
  std::cout << "  phase consistency RMS: " << b.at("phase_rms_px").get<double>() << " -> "
            << a.at("phase_rms_px").get<double>() << " px across the fringes ("
            << a.at("phase_samples").get<std::size_t>() << " samples)\n";
  if (s.contains("truth")) {
    for (const char* when : {"before", "after"}) {
      const json& e = s.at("truth").at(when);
      std::cout << "  vs truth " << when << ": main fx "
                << 100 * e.at("main").at("fx_rel").get<double>() << " %, aux fx "
                << 100 * e.at("aux").at("fx_rel").get<double>() << " %, rotation "
                << e.at("rotation_deg").get<double>() << " deg, T "
                << e.at("translation_mm").get<double>() << " mm\n";
    }
  }
}

void runRefineStereo(const RefineStereoRequest& request) {
  firmware::Stopwatch total;
  if (static_cast<int>(request.bundles.size()) < request.min_poses) {
    throw std::invalid_argument("refine-stereo: " + std::to_string(request.bundles.size()) +
                                " plane poses given, at least " +
                                std::to_string(request.min_poses) + " are needed");
  }
  const formats::StereoCalibration stereo = formats::readStereoCalibration(request.stereo);
  const algo::StereoGeometry initial = firmware::toStereoGeometry(stereo);
  const cv::Size size = initial.main.image_size;
  std::vector<firmware::Rejection> rejected;
  const algo::CheckerboardObservations boards = observeBoards(request, size, rejected);

  firmware::PlanePoseOptions pose_options;
  pose_options.phase = parsePhaseSource(request.phase);
  pose_options.stereo_pixels_only = true;
  pose_options.keep_aux_phase = true;
  const firmware::PlanePoseMeasurer measurer(initial, pose_options);
  std::vector<algo::PlanePoseObservation> poses;
  std::vector<std::string> names;
  firmware::Stopwatch watch;
  firmware::PoseOrderReference order_reference;
  for (const auto& dir : request.bundles) {
    const formats::CaptureBundleReader bundle(dir);
    firmware::requireCamera(bundle, "main");
    firmware::requireCamera(bundle, "aux");
    for (const char* camera : {"main", "aux"})
      firmware::requireStereoImageSize(request.stereo, stereo, bundle.frameSize(camera),
                                       bundle.dir() / camera);
    firmware::PlanePose pose = measurer.measure(bundle, order_reference.value());
    order_reference.follow(pose);
    poses.push_back({pose.phase, pose.phase_aux, cv::Mat(), pose.plane});
    names.push_back(pose.bundle);
  }
  const double measure_ms = watch.lapMs();

  algo::StereoRefinementOptions options;
  options.model = request.model;
  options.samples_per_pose = request.samples;
  const algo::StereoRefinementResult result =
      algo::refineStereoWithPhase(initial, boards, poses, options);
  const double refine_ms = watch.lapMs();
  formats::writeStereoCalibration(request.out, firmware::toStereoCalibration(result.geometry));

  json pose_list = json::array();
  for (std::size_t i = 0; i < names.size(); ++i) {
    pose_list.push_back({{"bundle", names[i]}, {"phase_rms_px", result.pose_phase_rms_px[i]}});
  }
  json rejections = json::array();
  for (const auto& r : rejected)
    rejections.push_back({{"id", r.id}, {"reason", r.reason}});
  json summary = {{"boards", boards.views.size()},
                  {"rejected", rejections},
                  {"poses", pose_list},
                  {"model", request.model},
                  {"unknowns", result.unknowns},
                  {"iterations", result.iterations},
                  {"converged", result.converged},
                  {"before", residualJson(result.before)},
                  {"after", residualJson(result.after)},
                  {"main", cameraJson(result.geometry.main)},
                  {"aux", cameraJson(result.geometry.aux)},
                  {"baseline_mm", cv::norm(result.geometry.translation)},
                  {"timings_ms",
                   {{"measure", measure_ms}, {"refine", refine_ms}, {"total", total.elapsedMs()}}},
                  {"out", request.out}};
  if (!request.truth.empty()) {
    const algo::StereoGeometry truth =
        firmware::toStereoGeometry(formats::readStereoCalibration(request.truth));
    summary["truth"] = {{"before", errorsAgainst(initial, truth)},
                        {"after", errorsAgainst(result.geometry, truth)}};
  }
  if (request.json) {
    std::cout << summary.dump() << "\n";
  } else {
    printSummary(summary);
  }
}

}  // namespace

void addRefineStereoCommand(CLI::App& app) {
  auto request = std::make_shared<RefineStereoRequest>();
  CLI::App* cmd = app.add_subcommand(
      "refine-stereo", "refine a stereo calibration with the phase of plane poses (main+aux)");
  cmd->add_option("bundles", request->bundles, "calibration bundles, one per plane pose")
      ->required();
  cmd->add_option("--stereo", request->stereo, "initial stereo calibration (docs/formats.md)")
      ->required();
  cmd->add_option("--board", request->board,
                  "the checkerboard set it was made from (docs/formats.md)")
      ->required();
  cmd->add_option("--out", request->out, "refined stereo calibration to write")->required();
  cmd->add_option("--model", request->model,
                  "distortion coefficients refined: k1k2p1p2k3 (default), k1k2p1p2 or k1k2")
      ->check(CLI::IsMember({"k1k2p1p2k3", "k1k2p1p2", "k1k2"}));
  cmd->add_option("--phase", request->phase, "absolute phase matched: fused (default) or high")
      ->check(CLI::IsMember({"high", "fused"}));
  cmd->add_option("--samples", request->samples, "main pixels sampled per pose (default 3000)")
      ->check(CLI::Range(100, 1000000));
  cmd->add_option("--truth", request->truth,
                  "true stereo calibration (virtual head): report the errors before and after");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runRefineStereo(*request); });
}

}  // namespace cylscan::tools
