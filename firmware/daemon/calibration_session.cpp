// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/calibration_session.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <opencv2/calib3d.hpp>

#include "firmware/checkerboard_corners.hpp"
#include "firmware/daemon/log.hpp"
#include "formats/atomic_file.hpp"

namespace cylscan::firmware {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr int kGridCells = 4;  // coverage: the image as 4 × 4 cells
constexpr int kMinPairsForGuidance = 4;

json pointsJson(const std::vector<cv::Point2f>& points) {
  json out = json::array();
  for (const auto& p : points)
    out.push_back({p.x, p.y});
  return out;
}

std::vector<cv::Point2f> pointsFrom(const json& j) {
  std::vector<cv::Point2f> out;
  for (const json& p : j)
    out.emplace_back(p.at(0).get<float>(), p.at(1).get<float>());
  return out;
}

json optionalJson(const std::optional<double>& v) {
  return v ? json(*v) : json(nullptr);
}

std::optional<double> optionalNumber(const json& j, const char* key) {
  if (!j.contains(key) || j.at(key).is_null()) return std::nullopt;
  return j.at(key).get<double>();
}

std::optional<std::string> optionalString(const json& j, const char* key) {
  if (!j.contains(key) || j.at(key).is_null()) return std::nullopt;
  return j.at(key).get<std::string>();
}

// One camera's fit over the kept views and what it pins down: the solve's
// model (k1 k2 p1 p2 k3, firmware/stereo_solve.hpp), started from the last
// fit when there is one, so that a view more costs a few iterations instead
// of a fit from scratch (the solve itself iterates to convergence).
ViewGuidance guideCamera(const formats::CheckerboardInfo& board,
                         const std::vector<std::vector<cv::Point2f>>& views, cv::Size image,
                         CameraGuess& guess) {
  const auto object = boardPoints(board);
  std::vector<std::vector<cv::Point3f>> objects(views.size(), object);
  cv::Mat k = guess.camera_matrix.clone(), d = guess.dist_coeffs.clone();
  cv::Mat intrinsics_sigma, extrinsics_sigma, per_view;
  std::vector<cv::Mat> rvecs, tvecs;
  ViewGuidance g;
  // From the last fit a few iterations suffice: one view more moves the
  // intrinsics little, and the sigmas come from the Jacobian where the fit
  // stops. Each iteration solves for every view's pose as well, so their
  // count is the cost (about 50 ms each at 64 views).
  const bool guessed = !k.empty();
  const int flags = guessed ? cv::CALIB_USE_INTRINSIC_GUESS : 0;
  // The overload with the standard deviations (calibrateCameraExtended's).
  g.rms_px = cv::calibrateCamera(
      objects, views, image, k, d, rvecs, tvecs, intrinsics_sigma, extrinsics_sigma, per_view,
      flags,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, guessed ? 3 : 30, 1e-6));
  guess.camera_matrix = k;
  guess.dist_coeffs = d;
  g.focal_px = 0.5 * (k.at<double>(0, 0) + k.at<double>(1, 1));
  g.sigma_fx = intrinsics_sigma.at<double>(0);
  g.sigma_fy = intrinsics_sigma.at<double>(1);
  g.sigma_cx = intrinsics_sigma.at<double>(2);
  g.sigma_cy = intrinsics_sigma.at<double>(3);
  std::vector<bool> cells(static_cast<std::size_t>(kGridCells) * kGridCells, false);
  for (const auto& view : views)
    for (const auto& p : view) {
      const int cx =
          std::clamp(static_cast<int>(p.x * kGridCells / image.width), 0, kGridCells - 1);
      const int cy =
          std::clamp(static_cast<int>(p.y * kGridCells / image.height), 0, kGridCells - 1);
      cells[cy * kGridCells + cx] = true;
    }
  g.coverage = static_cast<double>(std::count(cells.begin(), cells.end(), true)) / cells.size();
  for (const cv::Mat& r : rvecs) {
    cv::Matx33d rotation;
    cv::Rodrigues(r, rotation);
    // The board's normal in the camera frame against the optical axis.
    const double c = std::clamp(std::abs(rotation(2, 2)), 0.0, 1.0);
    g.max_tilt_deg = std::max(g.max_tilt_deg, std::acos(c) * 180.0 / CV_PI);
  }
  return g;
}

std::string fixed(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

// What a camera still lacks, or empty.
std::string lacking(const char* name, const ViewGuidance& g, const GuidanceLimits& limits) {
  std::string out;
  const auto add = [&](const std::string& what) {
    out += (out.empty() ? std::string(name) + ": " : std::string("; ")) + what;
  };
  if (g.coverage < limits.min_coverage)
    add("the corners cover " + fixed(100 * g.coverage, 0) + " % of the image (need " +
        fixed(100 * limits.min_coverage, 0) + " %): hold the board nearer the corners and edges");
  if (g.max_tilt_deg < limits.min_tilt_deg)
    add("the boards tilt at most " + fixed(g.max_tilt_deg, 0) + "° (need " +
        fixed(limits.min_tilt_deg, 0) + "°): tilt the board more");
  const double centre = std::max(g.sigma_cx, g.sigma_cy) / g.focal_px;
  if (centre > limits.max_sigma_centre)
    add("σ of the principal point " + fixed(centre * g.focal_px, 2) + " px, " +
        fixed(1e3 * centre, 2) + " mrad (need ≤ " + fixed(1e3 * limits.max_sigma_centre, 2) +
        "): more views, tilted more, about both axes");
  const double f = std::max(g.sigma_fx, g.sigma_fy) / g.focal_px;
  if (f > limits.max_sigma_focal)
    add("σ of the focal length " + fixed(100 * f, 3) + " % (need ≤ " +
        fixed(100 * limits.max_sigma_focal, 3) + " %): more views at different distances");
  return out;
}

}  // namespace

CaptureGuidance guideCapture(const formats::CheckerboardInfo& board,
                             const std::vector<std::vector<cv::Point2f>>& main,
                             const std::vector<std::vector<cv::Point2f>>& aux, cv::Size image,
                             GuidanceGuess& guess, const GuidanceLimits& limits) {
  CaptureGuidance g;
  if (static_cast<int>(main.size()) < kMinPairsForGuidance) {
    g.advice = "take more checkerboard views: " + std::to_string(main.size()) + " kept, " +
               std::to_string(kMinPairsForGuidance) + " before the first estimate";
    return g;
  }
  g.main = guideCamera(board, main, image, guess.main);
  g.aux = guideCamera(board, aux, image, guess.aux);
  std::string advice = lacking("main", *g.main, limits);
  const std::string aux_advice = lacking("aux", *g.aux, limits);
  if (!aux_advice.empty()) advice += (advice.empty() ? "" : "; ") + aux_advice;
  if (static_cast<int>(main.size()) < limits.min_boards)
    advice = "take at least " + std::to_string(limits.min_boards) + " views (" +
             std::to_string(main.size()) + " kept)" + (advice.empty() ? "" : "; " + advice);
  g.enough = advice.empty();
  g.advice = g.enough ? "enough views: capture the plane poses" : advice;
  return g;
}

json toJson(const CaptureGuidance& g) {
  const auto camera = [](const std::optional<ViewGuidance>& v) -> json {
    if (!v) return nullptr;
    return {{"sigma_px",
             {{"fx", v->sigma_fx}, {"fy", v->sigma_fy}, {"cx", v->sigma_cx}, {"cy", v->sigma_cy}}},
            {"rms_px", v->rms_px},
            {"coverage", v->coverage},
            {"max_tilt_deg", v->max_tilt_deg}};
  };
  return {{"enough", g.enough},
          {"advice", g.advice},
          {"cameras", {{"main", camera(g.main)}, {"aux", camera(g.aux)}}}};
}

std::unique_ptr<CalibrationSession> CalibrationSession::create(fs::path dir,
                                                               formats::CheckerboardInfo board,
                                                               cv::Size image,
                                                               std::string created) {
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir / "planes");
  auto s = std::make_unique<CalibrationSession>(std::move(dir), board, image);
  std::lock_guard lock(s->mutex_);
  s->s_.created = std::move(created);
  s->saveLocked();
  return s;
}

std::unique_ptr<CalibrationSession> CalibrationSession::load(const fs::path& dir, cv::Size image) {
  const fs::path file = dir / "session.json";
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return nullptr;
  try {
    std::ifstream in(file);
    const nlohmann::json j = nlohmann::json::parse(in);
    formats::CheckerboardInfo board{j.at("board").at("cols").get<int>(),
                                    j.at("board").at("rows").get<int>(),
                                    j.at("board").at("square_mm").get<double>()};
    auto s = std::make_unique<CalibrationSession>(dir, board, image);
    std::unique_lock fill(s->mutex_);  // the guidance thread reads the boards
    SessionState& st = s->s_;
    st.state = j.at("state").get<std::string>();
    st.created = j.at("created").get<std::string>();
    // A solve does not survive the process that ran it.
    if (st.state == "solving") {
      st.state = "failed";
      st.error = "the daemon stopped while solving: solve again";
    } else {
      st.error = optionalString(j, "error");
    }
    st.progress = j.value("progress", 0.0);
    if (j.contains("result") && !j.at("result").is_null()) st.result = j.at("result");
    for (const json& b : j.at("boards")) {
      SessionBoard board_entry;
      board_entry.index = b.at("index").get<int>();
      board_entry.found_main = b.at("found").at("main").get<bool>();
      board_entry.found_aux = b.at("found").at("aux").get<bool>();
      board_entry.scene = optionalString(b, "scene");
      if (b.contains("corners")) {
        board_entry.main = pointsFrom(b.at("corners").at("main"));
        board_entry.aux = pointsFrom(b.at("corners").at("aux"));
      }
      st.boards.push_back(std::move(board_entry));
    }
    for (const json& p : j.at("planes")) {
      SessionPlane plane;
      plane.index = p.at("index").get<int>();
      plane.state = p.at("state").get<std::string>();
      if (plane.state == "capturing") {
        plane.state = "failed";
        plane.error = "the daemon stopped during the capture";
      } else {
        plane.error = optionalString(p, "error");
      }
      plane.scene = optionalString(p, "scene");
      plane.valid_fraction = optionalNumber(p, "valid_fraction");
      plane.rmse_mm = optionalNumber(p, "rmse_mm");
      st.planes.push_back(std::move(plane));
    }
    fill.unlock();
    s->cv_.notify_all();  // the kept pairs' guidance
    return s;
  } catch (const std::exception& e) {
    logWarn("the calibration session in " + dir.string() + " cannot be read (" + e.what() +
            "); it is discarded");
    fs::remove_all(dir, ec);
    return nullptr;
  }
}

fs::path CalibrationSession::planeDir(int index) const {
  char name[16];
  std::snprintf(name, sizeof name, "%02d", index);
  return dir_ / "planes" / name;
}

SessionState CalibrationSession::state() const {
  std::lock_guard lock(mutex_);
  return s_;
}

json CalibrationSession::describe() const {
  std::lock_guard lock(mutex_);
  nlohmann::json boards = nlohmann::json::array();
  for (const SessionBoard& b : s_.boards) {
    nlohmann::json e = {{"index", b.index},
                        {"found", {{"main", b.found_main}, {"aux", b.found_aux}}}};
    if (b.scene) e["scene"] = *b.scene;
    boards.push_back(std::move(e));
  }
  nlohmann::json planes = nlohmann::json::array();
  for (const SessionPlane& p : s_.planes) {
    nlohmann::json e = {{"index", p.index}, {"state", p.state}};
    if (p.valid_fraction) e["valid_fraction"] = *p.valid_fraction;
    if (p.rmse_mm) e["rmse_mm"] = *p.rmse_mm;
    if (p.scene) e["scene"] = *p.scene;
    if (p.error) e["error"] = *p.error;
    planes.push_back(std::move(e));
  }
  nlohmann::json out = {{"state", s_.state},           {"created", s_.created},
                        {"boards", std::move(boards)}, {"planes", std::move(planes)},
                        {"progress", s_.progress},     {"guidance", toJson(s_.guidance)}};
  out["guidance"]["pairs"] = guided_pairs_;
  if (s_.result) out["result"] = *s_.result;
  if (s_.error) out["error"] = *s_.error;
  return out;
}

void CalibrationSession::saveLocked() const {
  nlohmann::json boards = nlohmann::json::array();
  for (const SessionBoard& b : s_.boards) {
    nlohmann::json e = {{"index", b.index},
                        {"found", {{"main", b.found_main}, {"aux", b.found_aux}}},
                        {"scene", b.scene ? nlohmann::json(*b.scene) : nlohmann::json(nullptr)}};
    if (!b.main.empty()) e["corners"] = {{"main", pointsJson(b.main)}, {"aux", pointsJson(b.aux)}};
    boards.push_back(std::move(e));
  }
  nlohmann::json planes = nlohmann::json::array();
  for (const SessionPlane& p : s_.planes)
    planes.push_back({{"index", p.index},
                      {"state", p.state},
                      {"scene", p.scene ? nlohmann::json(*p.scene) : nlohmann::json(nullptr)},
                      {"valid_fraction", optionalJson(p.valid_fraction)},
                      {"rmse_mm", optionalJson(p.rmse_mm)},
                      {"error", p.error ? nlohmann::json(*p.error) : nlohmann::json(nullptr)}});
  const nlohmann::json j = {
      {"board", {{"cols", board_.cols}, {"rows", board_.rows}, {"square_mm", board_.square_mm}}},
      {"state", s_.state},
      {"created", s_.created},
      {"progress", s_.progress},
      {"result", s_.result ? *s_.result : nlohmann::json(nullptr)},
      {"error", s_.error ? nlohmann::json(*s_.error) : nlohmann::json(nullptr)},
      {"boards", std::move(boards)},
      {"planes", std::move(planes)}};
  formats::writeFileAtomically(dir_ / "session.json", j.dump());
}

CalibrationSession::CalibrationSession(fs::path dir, formats::CheckerboardInfo board,
                                       cv::Size image)
    : dir_(std::move(dir)), board_(board), image_(image) {
  s_.guidance.advice = "take more checkerboard views: 0 kept, " +
                       std::to_string(kMinPairsForGuidance) + " before the first estimate";
  guidance_thread_ = std::thread([this] { guide(); });
}

CalibrationSession::~CalibrationSession() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (guidance_thread_.joinable()) guidance_thread_.join();
}

std::size_t CalibrationSession::keptCountLocked() const {
  return static_cast<std::size_t>(std::count_if(
      s_.boards.begin(), s_.boards.end(), [](const SessionBoard& b) { return !b.main.empty(); }));
}

bool CalibrationSession::waitGuided(std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mutex_);
  return cv_.wait_for(lock, timeout, [&] { return guided_pairs_ == keptCountLocked(); });
}

void CalibrationSession::guide() {
  for (;;) {
    std::vector<std::vector<cv::Point2f>> main, aux;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [&] { return stopping_ || guided_pairs_ != keptCountLocked(); });
      if (stopping_) return;
      for (const SessionBoard& b : s_.boards)
        if (!b.main.empty()) {
          main.push_back(b.main);
          aux.push_back(b.aux);
        }
    }
    CaptureGuidance guidance;
    try {
      guidance = guideCapture(board_, main, aux, image_, guess_);
    } catch (const cv::Exception& e) {
      guess_ = GuidanceGuess{};
      guidance.advice =
          std::string("the views cannot be fitted yet (") + e.what() + "): take more, tilted views";
    }
    {
      std::lock_guard lock(mutex_);
      s_.guidance = std::move(guidance);
      guided_pairs_ = main.size();
    }
    cv_.notify_all();
  }
}

int CalibrationSession::addBoard(SessionBoard board) {
  std::lock_guard lock(mutex_);
  board.index = static_cast<int>(s_.boards.size());
  if (!(board.found_main && board.found_aux)) {
    board.main.clear();
    board.aux.clear();
  }
  const bool kept = !board.main.empty();
  s_.boards.push_back(std::move(board));
  saveLocked();
  if (kept) cv_.notify_all();
  return s_.boards.back().index;
}

int CalibrationSession::beginPlane(std::optional<std::string> scene) {
  std::lock_guard lock(mutex_);
  SessionPlane p;
  p.index = static_cast<int>(s_.planes.size());
  p.scene = std::move(scene);
  s_.planes.push_back(std::move(p));
  saveLocked();
  return s_.planes.back().index;
}

void CalibrationSession::finishPlane(int index, std::optional<std::string> error) {
  std::lock_guard lock(mutex_);
  SessionPlane& p = s_.planes.at(static_cast<std::size_t>(index));
  p.state = error ? "failed" : "done";
  p.error = std::move(error);
  saveLocked();
}

void CalibrationSession::setSolving() {
  std::lock_guard lock(mutex_);
  s_.state = "solving";
  s_.progress = 0;
  s_.result.reset();
  s_.error.reset();
  saveLocked();
}

void CalibrationSession::setProgress(double progress) {
  std::lock_guard lock(mutex_);
  s_.progress = progress;  // not saved: a solve does not survive a restart
}

void CalibrationSession::setSolved(nlohmann::json result, const std::vector<SessionPlane>& planes) {
  std::lock_guard lock(mutex_);
  s_.state = "solved";
  s_.progress = 1;
  s_.result = std::move(result);
  for (const SessionPlane& solved : planes)
    for (SessionPlane& p : s_.planes)
      if (p.index == solved.index) {
        p.valid_fraction = solved.valid_fraction;
        p.rmse_mm = solved.rmse_mm;
      }
  saveLocked();
}

void CalibrationSession::setFailed(std::string error) {
  std::lock_guard lock(mutex_);
  s_.state = "failed";
  s_.error = std::move(error);
  saveLocked();
}

std::vector<SessionPlane> CalibrationSession::donePlanes() const {
  std::lock_guard lock(mutex_);
  std::vector<SessionPlane> out;
  for (const SessionPlane& p : s_.planes)
    if (p.state == "done") out.push_back(p);
  return out;
}

std::vector<SessionBoard> CalibrationSession::keptBoards() const {
  std::lock_guard lock(mutex_);
  std::vector<SessionBoard> out;
  for (const SessionBoard& b : s_.boards)
    if (!b.main.empty()) out.push_back(b);
  return out;
}

}  // namespace cylscan::firmware
