// SPDX-License-Identifier: Apache-2.0
// The head's own calibration session: checkerboard pairs (their corners),
// plane poses (two-camera capture bundles), the solve's progress and result,
// kept in DATA/calibration-session/ (session.json rewritten atomically after
// each change, the bundles in planes/NN/), so a restart of the daemon loses
// no view already taken.
//
// It also says how well the views so far pin each camera down: the standard
// deviations of fx, fy, cx and cy (cv::calibrateCameraExtended over the
// kept pairs), the share of the image the corners cover and the spread of the
// board tilts, and whether that is enough (CaptureGuidance).
#pragma once

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "formats/checkerboard_set.hpp"

namespace cylscan::firmware {

// What the kept views determine of one camera.
struct ViewGuidance {
  double sigma_fx = 0, sigma_fy = 0, sigma_cx = 0, sigma_cy = 0;  // px, one standard deviation
  double focal_px = 0;      // the fit's (fx + fy) / 2, the scale of the focal limit
  double rms_px = 0;        // the fit's reprojection error
  double coverage = 0;      // share of the image's 4 × 4 cells holding corners
  double max_tilt_deg = 0;  // the largest angle of a board to the image plane
};

// Whether the views suffice and, if not, what to take next.
struct CaptureGuidance {
  std::optional<ViewGuidance> main, aux;  // once enough pairs for a fit
  bool enough = false;
  std::string advice;
};

// The last fit of a camera, where the next one starts (empty: none yet).
struct CameraGuess {
  cv::Mat camera_matrix, dist_coeffs;
};
struct GuidanceGuess {
  CameraGuess main, aux;
};

// The limits a session's views must meet (README, "Calibration on the head").
struct GuidanceLimits {
  int min_boards = 10;
  // σ(cx), σ(cy) over f: the direction of the camera frame, rad (1 mrad is
  // 0.6 mm across at the working distance of 580 mm).
  double max_sigma_centre = 1e-3;
  // σ(fx), σ(fy) over f: the scale of what the head measures (0.1 % is
  // 0.05 mm on the 50 mm sphere's radius, the accuracy the head promises).
  double max_sigma_focal = 1e-3;
  double min_coverage = 0.5;
  double min_tilt_deg = 20;
};

// The guidance from the corners of the kept pairs (main's and aux's, same
// order), the board and the image size.
CaptureGuidance guideCapture(const formats::CheckerboardInfo& board,
                             const std::vector<std::vector<cv::Point2f>>& main,
                             const std::vector<std::vector<cv::Point2f>>& aux, cv::Size image,
                             GuidanceGuess& guess, const GuidanceLimits& limits = {});
nlohmann::json toJson(const CaptureGuidance& guidance);

struct SessionBoard {
  int index = 0;
  bool found_main = false, found_aux = false;
  std::optional<std::string> scene;
  std::vector<cv::Point2f> main, aux;  // kept only when both found
};

struct SessionPlane {
  int index = 0;
  std::string state = "capturing";  // capturing | done | failed
  std::optional<std::string> scene;
  std::optional<double> valid_fraction;  // main's, once solved
  std::optional<double> rmse_mm;         // the fit's against this pose, once solved
  std::optional<std::string> error;
};

struct SessionState {
  std::string state = "capturing";  // capturing | solving | solved | failed
  std::string created;
  std::vector<SessionBoard> boards;  // every pair tried; the kept ones have corners
  std::vector<SessionPlane> planes;
  double progress = 0;
  std::optional<nlohmann::json> result;
  std::optional<std::string> error;
  CaptureGuidance guidance;
};

class CalibrationSession {
 public:
  // A new session in `dir` (anything there is removed first).
  static std::unique_ptr<CalibrationSession> create(std::filesystem::path dir,
                                                    formats::CheckerboardInfo board, cv::Size image,
                                                    std::string created);
  // The session kept in `dir`; nullptr when there is none or it cannot be
  // read (then it is removed, with a warning).
  static std::unique_ptr<CalibrationSession> load(const std::filesystem::path& dir, cv::Size image);

  const std::filesystem::path& dir() const { return dir_; }
  const formats::CheckerboardInfo& board() const { return board_; }
  std::filesystem::path planeDir(int index) const;
  std::filesystem::path calibrationFile() const { return dir_ / "main.qcal"; }
  std::filesystem::path stereoFile() const { return dir_ / "stereo.json"; }

  SessionState state() const;
  nlohmann::json describe() const;  // GET /api/v1/calibration/session

  // Each change is written to session.json before it returns.
  int addBoard(SessionBoard board);  // its index; the guidance follows
  int beginPlane(std::optional<std::string> scene);
  void finishPlane(int index, std::optional<std::string> error);
  void setSolving();
  void setProgress(double progress);
  void setSolved(nlohmann::json result, const std::vector<SessionPlane>& planes);
  void setFailed(std::string error);
  // The planes whose capture is done, in order, and the kept pairs' corners.
  std::vector<SessionPlane> donePlanes() const;
  std::vector<SessionBoard> keptBoards() const;

  // Waits until the guidance reflects every pair kept so far (tests, and a
  // solve that wants the last figures); false on timeout.
  bool waitGuided(std::chrono::milliseconds timeout) const;

  // Starts the guidance thread.
  CalibrationSession(std::filesystem::path dir, formats::CheckerboardInfo board, cv::Size image);
  // Stops and joins the guidance thread (a fit under way is finished first).
  ~CalibrationSession();
  CalibrationSession(const CalibrationSession&) = delete;
  CalibrationSession& operator=(const CalibrationSession&) = delete;

 private:
  void saveLocked() const;
  std::size_t keptCountLocked() const;
  // The guidance thread: refits whenever pairs were kept since its last
  // fit, so that a capture never waits for the fits (a second or more once
  // there are many pairs) and the fits of pairs taken quickly coalesce.
  void guide();

  std::filesystem::path dir_;
  formats::CheckerboardInfo board_;
  cv::Size image_;
  mutable std::mutex mutex_;
  mutable std::condition_variable cv_;
  SessionState s_;
  std::size_t guided_pairs_ = 0;  // kept pairs the guidance reflects
  bool stopping_ = false;
  GuidanceGuess guess_;  // the last guidance's fits (the guidance thread's)
  std::thread guidance_thread_;
};

}  // namespace cylscan::firmware
