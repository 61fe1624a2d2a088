// SPDX-License-Identifier: Apache-2.0
// cylscan calibrate-stereo: the stereo calibration file of the main and aux
// cameras from a checkerboard set (both in docs/formats.md).
//
// Corners: cv::findChessboardCorners (adaptive threshold, normalised image),
// then cv::cornerSubPix with a window sized to the board's squares. Each
// camera: cv::calibrateCamera (k1 k2 p1 p2 k3) on the pairs where both cameras
// found the board; a pair whose view reprojects worse than max(3 × median,
// 0.5 px) in either camera is an outlier, dropped, and both cameras are
// calibrated again without it. The pair: cv::stereoCalibrate with
// CALIB_FIX_INTRINSIC, i.e. only R and T (6 parameters) are estimated from
// all pairs. Why not a joint refinement: each camera's intrinsics are already
// fitted to every usable view of that camera, the extrinsics then come from a
// small, well-conditioned problem, and a per-camera RMS printed by this tool
// stays the RMS of the intrinsics that are written. --refine-jointly runs the
// joint refinement (CALIB_USE_INTRINSIC_GUESS) for comparison; the per-camera
// RMS printed is then the joint model's, the one written (the parameters'
// sigmas stay those of the separate fits, the only ones OpenCV estimates).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/checkerboard_set.hpp"
#include "formats/input_error.hpp"
#include "formats/png.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/checkerboard_corners.hpp"
#include "tools/commands.hpp"
#include "tools/stereo_geometry.hpp"
#include "tools/stopwatch.hpp"

namespace cylscan::tools {
namespace {

// A view whose RMS reprojection error exceeds max(kOutlierFactor × median,
// kOutlierFloorPx) is an outlier: a misdetected corner or a blurred board.
constexpr double kOutlierFactor = 3.0;
constexpr double kOutlierFloorPx = 0.5;

struct CalibrateStereoRequest {
  std::string board;
  std::string out;
  int min_pairs = 6;
  std::string model = "k1k2p1p2k3";
  bool refine_jointly = false;
  bool json = false;
};

struct CameraFit {
  cv::Matx33d camera_matrix;
  cv::Vec<double, 5> dist_coeffs;
  double rms_px = 0;
  std::vector<double> view_rms_px;
  // One standard deviation of fx fy cx cy k1 k2 p1 p2 k3 (cv::calibrateCamera's
  // estimate from the residuals): how well the views determine each parameter.
  std::vector<double> sigma;
};

double viewRms(const std::vector<cv::Point3f>& object, const Corners& corners, const cv::Matx33d& k,
               const cv::Vec<double, 5>& dist, const cv::Mat& rvec, const cv::Mat& tvec) {
  Corners projected;
  cv::projectPoints(object, rvec, tvec, k, dist, projected);
  double sum = 0;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const cv::Point2f d = projected[i] - corners[i];
    sum += d.dot(d);
  }
  return std::sqrt(sum / static_cast<double>(corners.size()));
}

// The cv::calibrateCamera flags of a distortion model; the file always holds
// k1 k2 p1 p2 k3, the coefficients a model leaves out are 0.
int modelFlags(const std::string& model) {
  if (model == "k1k2p1p2k3") return 0;
  if (model == "k1k2p1p2") return cv::CALIB_FIX_K3;
  if (model == "k1k2") return cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
  throw std::invalid_argument("calibrate-stereo: unknown distortion model '" + model + "'");
}

CameraFit calibrateCamera(const std::vector<std::vector<cv::Point3f>>& object,
                          const std::vector<Corners>& corners, cv::Size size, int flags) {
  CameraFit fit;
  cv::Mat k, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat sigma_intrinsics, sigma_extrinsics, per_view;
  fit.rms_px = cv::calibrateCamera(
      object, corners, size, k, dist, rvecs, tvecs, sigma_intrinsics, sigma_extrinsics, per_view,
      flags, cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  fit.camera_matrix = cv::Matx33d(k);
  for (int i = 0; i < 5; ++i)
    fit.dist_coeffs[i] = dist.at<double>(i);
  for (int i = 0; i < 9; ++i)
    fit.sigma.push_back(sigma_intrinsics.at<double>(i));
  for (std::size_t v = 0; v < corners.size(); ++v) {
    fit.view_rms_px.push_back(
        viewRms(object[v], corners[v], fit.camera_matrix, fit.dist_coeffs, rvecs[v], tvecs[v]));
  }
  return fit;
}

double median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2),
                   values.end());
  return values[values.size() / 2];
}

double outlierThreshold(const CameraFit& fit) {
  return std::max(kOutlierFactor * median(fit.view_rms_px), kOutlierFloorPx);
}

std::string px(double value) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(3) << value << " px";
  return text.str();
}

struct StereoFit {
  CameraFit main, aux;
  cv::Matx33d rotation;
  cv::Vec3d translation;
  double rms_px = 0;
  std::vector<double> view_rms_px;  // per pair, both cameras
  std::vector<std::string> ids;     // the pairs used
};

class StereoCalibrator {
 public:
  StereoCalibrator(const formats::CheckerboardInfo& board, cv::Size size,
                   const CalibrateStereoRequest& request)
      : object_(boardPoints(board)),
        size_(size),
        min_pairs_(request.min_pairs),
        model_flags_(modelFlags(request.model)),
        refine_jointly_(request.refine_jointly) {}

  StereoFit run(std::vector<PairCorners> pairs, std::vector<Rejection>& rejected) const {
    requireEnough(pairs, rejected);
    StereoFit fit;
    fitCameras(pairs, fit);
    if (dropOutliers(pairs, fit, rejected)) {
      requireEnough(pairs, rejected, " after dropping the reprojection outliers");
      fitCameras(pairs, fit);
    }
    fitPair(pairs, fit);
    return fit;
  }

 private:
  // `when`: empty with the board found, else when the pairs were counted.
  void requireEnough(const std::vector<PairCorners>& pairs, const std::vector<Rejection>& rejected,
                     const std::string& when = "") const {
    if (static_cast<int>(pairs.size()) >= min_pairs_) return;
    std::string reasons;
    for (const auto& r : rejected)
      reasons += "; " + r.id + ": " + r.reason;
    throw std::runtime_error("calibrate-stereo: only " + std::to_string(pairs.size()) +
                             " usable checkerboard pairs" + when + ", at least " +
                             std::to_string(min_pairs_) +
                             " (--min-pairs) are needed; nothing "
                             "written" +
                             reasons);
  }

  std::vector<std::vector<cv::Point3f>> objects(std::size_t n) const {
    return std::vector<std::vector<cv::Point3f>>(n, object_);
  }

  void fitCameras(const std::vector<PairCorners>& pairs, StereoFit& fit) const {
    std::vector<Corners> main, aux;
    for (const auto& p : pairs) {
      main.push_back(p.main);
      aux.push_back(p.aux);
    }
    fit.main = calibrateCamera(objects(pairs.size()), main, size_, model_flags_);
    fit.aux = calibrateCamera(objects(pairs.size()), aux, size_, model_flags_);
  }

  // Removes the pairs that are reprojection outliers in either camera.
  static bool dropOutliers(std::vector<PairCorners>& pairs, const StereoFit& fit,
                           std::vector<Rejection>& rejected) {
    const double main_limit = outlierThreshold(fit.main);
    const double aux_limit = outlierThreshold(fit.aux);
    std::vector<PairCorners> kept;
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const double em = fit.main.view_rms_px[i];
      const double ea = fit.aux.view_rms_px[i];
      if (em > main_limit || ea > aux_limit) {
        rejected.push_back({pairs[i].id, "reprojection outlier (main " + px(em) + " vs limit " +
                                             px(main_limit) + ", aux " + px(ea) + " vs limit " +
                                             px(aux_limit) + ")"});
      } else {
        kept.push_back(std::move(pairs[i]));
      }
    }
    const bool dropped = kept.size() != pairs.size();
    pairs = std::move(kept);
    return dropped;
  }

  void fitPair(const std::vector<PairCorners>& pairs, StereoFit& fit) const {
    std::vector<Corners> main, aux;
    for (const auto& p : pairs) {
      main.push_back(p.main);
      aux.push_back(p.aux);
      fit.ids.push_back(p.id);
    }
    cv::Mat k1(fit.main.camera_matrix), d1(fit.main.dist_coeffs), k2(fit.aux.camera_matrix),
        d2(fit.aux.dist_coeffs);
    cv::Mat r, t, e, f, per_view;
    const int flags =
        refine_jointly_ ? cv::CALIB_USE_INTRINSIC_GUESS | model_flags_ : cv::CALIB_FIX_INTRINSIC;
    fit.rms_px = cv::stereoCalibrate(
        objects(pairs.size()), main, aux, k1, d1, k2, d2, size_, r, t, e, f, per_view, flags,
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
    fit.main.camera_matrix = cv::Matx33d(k1);
    fit.aux.camera_matrix = cv::Matx33d(k2);
    for (int i = 0; i < 5; ++i) {
      fit.main.dist_coeffs[i] = d1.at<double>(i);
      fit.aux.dist_coeffs[i] = d2.at<double>(i);
    }
    fit.rotation = cv::Matx33d(r);
    fit.translation = cv::Vec3d(t.at<double>(0), t.at<double>(1), t.at<double>(2));
    double sum_main = 0, sum_aux = 0;
    for (int v = 0; v < per_view.rows; ++v) {
      const double a = per_view.at<double>(v, 0), b = per_view.at<double>(v, 1);
      fit.view_rms_px.push_back(std::sqrt(0.5 * (a * a + b * b)));
      if (refine_jointly_) {
        // The written intrinsics are the joint model's: so are the RMS shown.
        fit.main.view_rms_px[static_cast<std::size_t>(v)] = a;
        fit.aux.view_rms_px[static_cast<std::size_t>(v)] = b;
      }
      sum_main += a * a;
      sum_aux += b * b;
    }
    if (refine_jointly_ && per_view.rows > 0) {
      // Every view has the board's corner count: the RMS of the views' RMS.
      fit.main.rms_px = std::sqrt(sum_main / per_view.rows);
      fit.aux.rms_px = std::sqrt(sum_aux / per_view.rows);
    }
  }

  std::vector<cv::Point3f> object_;
  cv::Size size_;
  int min_pairs_;
  int model_flags_;
  bool refine_jointly_;
};

formats::StereoCalibration toFile(const StereoFit& fit, cv::Size size) {
  algo::StereoGeometry geometry;
  geometry.main = {fit.main.camera_matrix, fit.main.dist_coeffs, size};
  geometry.aux = {fit.aux.camera_matrix, fit.aux.dist_coeffs, size};
  geometry.rotation = fit.rotation;
  geometry.translation = fit.translation;
  return toStereoCalibration(geometry);
}

nlohmann::json cameraJson(const CameraFit& fit) {
  const cv::Matx33d& k = fit.camera_matrix;
  return {{"rms_px", fit.rms_px},
          {"fx", k(0, 0)},
          {"fy", k(1, 1)},
          {"cx", k(0, 2)},
          {"cy", k(1, 2)},
          {"dist_coeffs", std::vector<double>(fit.dist_coeffs.val, fit.dist_coeffs.val + 5)},
          {"sigma_fx_fy_cx_cy_k1_k2_p1_p2_k3", fit.sigma}};
}

nlohmann::json summaryJson(const CalibrateStereoRequest& request, const StereoFit& fit,
                           std::size_t pair_count, const std::vector<Rejection>& rejected,
                           cv::Size size, double total_ms) {
  nlohmann::json rejections = nlohmann::json::array();
  for (const auto& r : rejected)
    rejections.push_back({{"id", r.id}, {"reason", r.reason}});
  nlohmann::json views = nlohmann::json::array();
  for (std::size_t i = 0; i < fit.ids.size(); ++i) {
    views.push_back({{"id", fit.ids[i]},
                     {"main_rms_px", fit.main.view_rms_px[i]},
                     {"aux_rms_px", fit.aux.view_rms_px[i]},
                     {"stereo_rms_px", fit.view_rms_px[i]}});
  }
  return {{"width", size.width},
          {"height", size.height},
          {"pairs", pair_count},
          {"pairs_used", fit.ids.size()},
          {"rejected", rejections},
          {"main", cameraJson(fit.main)},
          {"aux", cameraJson(fit.aux)},
          {"stereo_rms_px", fit.rms_px},
          {"model", request.model},
          {"refinement", request.refine_jointly ? "joint" : "fixed-intrinsics"},
          {"baseline_mm", cv::norm(fit.translation)},
          {"T_mm", {fit.translation[0], fit.translation[1], fit.translation[2]}},
          {"views", views},
          {"timings_ms", {{"total", total_ms}}},
          {"out", request.out}};
}

void printSummary(const StereoFit& fit, std::size_t pair_count,
                  const std::vector<Rejection>& rejected) {
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "calibrate-stereo: " << fit.ids.size() << " of " << pair_count << " pairs used\n";
  for (const auto& [name, cam] : {std::pair{"main", &fit.main}, std::pair{"aux", &fit.aux}}) {
    const cv::Matx33d& k = cam->camera_matrix;
    std::cout << "  " << name << ": RMS " << cam->rms_px << " px, fx " << k(0, 0) << " fy "
              << k(1, 1) << " cx " << k(0, 2) << " cy " << k(1, 2) << "\n";
  }
  std::cout << "  stereo: RMS " << fit.rms_px << " px, baseline " << cv::norm(fit.translation)
            << " mm\n";
  for (const auto& r : rejected)
    std::cout << "  rejected " << r.id << ": " << r.reason << "\n";
}

void runCalibrateStereo(const CalibrateStereoRequest& request) {
  Stopwatch total;
  const formats::CheckerboardSet set = formats::readCheckerboardSet(request.board);
  std::vector<Rejection> rejected;
  cv::Size size;
  std::vector<PairCorners> pairs = detectPairs(set, size, rejected);
  if (pairs.empty() && !set.pairs.empty()) {
    // Found nowhere: most often cols × rows counts squares, not inner corners.
    throw formats::InputError(
        std::filesystem::path(request.board) / "checkerboard.json",
        "a board of " + std::to_string(set.board.cols) + " x " + std::to_string(set.board.rows) +
            " inner corners was found in none of the " + std::to_string(set.pairs.size()) +
            " pairs: check that cols and rows count inner corners (the "
            "squares less one)");
  }
  const StereoCalibrator calibrator(set.board, size, request);
  const StereoFit fit = calibrator.run(std::move(pairs), rejected);
  formats::writeStereoCalibration(request.out, toFile(fit, size));
  if (request.json) {
    std::cout
        << summaryJson(request, fit, set.pairs.size(), rejected, size, total.elapsedMs()).dump()
        << "\n";
  } else {
    printSummary(fit, set.pairs.size(), rejected);
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
