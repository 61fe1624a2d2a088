// SPDX-License-Identifier: Apache-2.0
#include "firmware/stereo_solve.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <utility>

#include <opencv2/calib3d.hpp>

#include "firmware/stereo_geometry.hpp"

namespace cylscan::firmware {
namespace {

// A view whose RMS reprojection error exceeds max(kOutlierFactor × median,
// kOutlierFloorPx) is an outlier: a misdetected corner or a blurred board.
constexpr double kOutlierFactor = 3.0;
constexpr double kOutlierFloorPx = 0.5;

// The progress of the solve's steps, as parts of the whole: each camera's
// fit, again without the outliers when there are some, then the pair's.
constexpr double kFirstFitEnd = 0.4;
constexpr double kRefitEnd = 0.8;

struct CameraFit {
  cv::Matx33d camera_matrix;
  cv::Vec<double, 5> dist_coeffs;
  double rms_px = 0;
  std::vector<double> view_rms_px;
  IntrinsicSigmas sigma;
};

struct StereoFit {
  CameraFit main, aux;
  cv::Matx33d rotation;
  cv::Vec3d translation;
  double rms_px = 0;
  std::vector<double> view_rms_px;  // per pair, both cameras
  std::vector<std::string> ids;     // the pairs used
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

// The cv::calibrateCamera flags of a distortion model; the calibration always
// holds k1 k2 p1 p2 k3, the coefficients a model leaves out are 0.
int modelFlags(const std::string& model) {
  if (model == "k1k2p1p2k3") return 0;
  if (model == "k1k2p1p2") return cv::CALIB_FIX_K3;
  if (model == "k1k2") return cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
  throw std::invalid_argument("unknown distortion model '" + model + "'");
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
  // stdDeviationsIntrinsics: fx fy cx cy k1 k2 p1 p2 k3, then the models not used here.
  fit.sigma.fx = sigma_intrinsics.at<double>(0);
  fit.sigma.fy = sigma_intrinsics.at<double>(1);
  fit.sigma.cx = sigma_intrinsics.at<double>(2);
  fit.sigma.cy = sigma_intrinsics.at<double>(3);
  for (int i = 0; i < 5; ++i)
    fit.sigma.dist_coeffs[i] = sigma_intrinsics.at<double>(4 + i);
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

class StereoCalibrator {
 public:
  StereoCalibrator(const formats::CheckerboardInfo& board, cv::Size size,
                   const StereoSolveOptions& options)
      : object_(boardPoints(board)),
        size_(size),
        min_pairs_(options.min_pairs),
        model_flags_(modelFlags(options.model)),
        refine_jointly_(options.refine_jointly) {}

  StereoFit run(std::vector<PairCorners> pairs, std::vector<Rejection>& rejected,
                ProgressSpan& progress) const {
    requireEnough(pairs, rejected, false);
    StereoFit fit;
    fitCameras(pairs, fit);
    progress(kFirstFitEnd);
    if (dropOutliers(pairs, fit, rejected)) {
      requireEnough(pairs, rejected, true);
      fitCameras(pairs, fit);
    }
    progress(kRefitEnd);
    fitPair(pairs, fit);
    return fit;
  }

 private:
  void requireEnough(const std::vector<PairCorners>& pairs, const std::vector<Rejection>& rejected,
                     bool after_outliers) const {
    if (static_cast<int>(pairs.size()) >= min_pairs_) return;
    throw TooFewPairs(pairs.size(), min_pairs_, after_outliers, rejected);
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
        // The intrinsics returned are the joint model's: so are the RMS.
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

StereoCameraResult cameraResult(const CameraFit& fit) {
  return {fit.camera_matrix, fit.dist_coeffs, fit.rms_px, fit.sigma};
}

StereoSolveResult resultOf(const StereoFit& fit, cv::Size size, std::size_t pair_count,
                           std::vector<Rejection> rejected) {
  algo::StereoGeometry geometry;
  geometry.main = {fit.main.camera_matrix, fit.main.dist_coeffs, size};
  geometry.aux = {fit.aux.camera_matrix, fit.aux.dist_coeffs, size};
  geometry.rotation = fit.rotation;
  geometry.translation = fit.translation;
  StereoSolveResult result;
  result.calibration = toStereoCalibration(geometry);
  result.image_size = size;
  result.pair_count = pair_count;
  result.main = cameraResult(fit.main);
  result.aux = cameraResult(fit.aux);
  result.stereo_rms_px = fit.rms_px;
  result.baseline_mm = cv::norm(fit.translation);
  for (std::size_t i = 0; i < fit.ids.size(); ++i) {
    result.views.push_back(
        {fit.ids[i], fit.main.view_rms_px[i], fit.aux.view_rms_px[i], fit.view_rms_px[i]});
  }
  result.rejected = std::move(rejected);
  return result;
}

std::string boardNotFoundText(const formats::CheckerboardInfo& board, std::size_t pair_count) {
  return "a board of " + std::to_string(board.cols) + " x " + std::to_string(board.rows) +
         " inner corners was found in none of the " + std::to_string(pair_count) +
         " pairs: check that cols and rows count inner corners (the squares less one)";
}

std::string reasonsText(const std::vector<Rejection>& rejected) {
  std::string reasons;
  for (const auto& r : rejected)
    reasons += "; " + r.id + ": " + r.reason;
  return reasons;
}

std::string tooFewText(std::size_t usable, int needed, bool after_outliers,
                       const std::vector<Rejection>& rejected) {
  return "only " + std::to_string(usable) + " usable checkerboard pairs" +
         (after_outliers ? " after dropping the reprojection outliers" : "") + ", at least " +
         std::to_string(needed) + " are needed" + reasonsText(rejected);
}

}  // namespace

BoardNotFound::BoardNotFound(const formats::CheckerboardInfo& board, std::size_t pair_count)
    : std::runtime_error(boardNotFoundText(board, pair_count)), pair_count_(pair_count) {}

TooFewPairs::TooFewPairs(std::size_t usable, int needed, bool after_outliers,
                         std::vector<Rejection> rejected)
    : std::runtime_error(tooFewText(usable, needed, after_outliers, rejected)),
      usable_(usable),
      needed_(needed),
      after_outliers_(after_outliers),
      rejected_(std::move(rejected)) {}

std::string TooFewPairs::reasons() const {
  return reasonsText(rejected_);
}

StereoSolveResult solveStereo(const formats::CheckerboardInfo& board, StereoCorners corners,
                              const StereoSolveOptions& options, const SolveProgress& progress) {
  ProgressSpan report(progress, 0.0, 1.0);
  report(0.0);
  if (corners.pairs.empty() && corners.pair_count > 0)
    throw BoardNotFound(board, corners.pair_count);
  const StereoCalibrator calibrator(board, corners.image_size, options);
  std::vector<Rejection> rejected = std::move(corners.rejected);
  const StereoFit fit = calibrator.run(std::move(corners.pairs), rejected, report);
  StereoSolveResult result =
      resultOf(fit, corners.image_size, corners.pair_count, std::move(rejected));
  report(1.0);
  return result;
}

StereoSolveResult solveStereo(const formats::CheckerboardInfo& board,
                              const std::vector<StereoPairImages>& pairs,
                              const StereoSolveOptions& options, const SolveProgress& progress) {
  // Corner detection and the fits take similar times on the head's images.
  ProgressSpan report(progress, 0.0, 1.0);
  StereoCorners corners = detectStereoCorners(board, pairs, report.part(0.0, 0.5));
  return solveStereo(board, std::move(corners), options, report.part(0.5, 1.0));
}

}  // namespace cylscan::firmware
