// SPDX-License-Identifier: Apache-2.0
// ScanService's calibration session: checkerboard pairs and plane poses
// taken by the worker through the acquisition like any scan, the solve
// (firmware/stereo_solve.hpp, then firmware/quasi_solve.hpp) on a thread of
// its own with its progress in the session and the event stream, the
// install that keeps the calibration it replaces, and the rollback to it.
//
// A checkerboard pair is the mean of every frame of a scan plan in both
// cameras: each fringe set's frames span whole periods in equal steps, so
// their mean is the projector's light without its fringes (the background
// of the N-step phase), the uniform light the corners need, on a real head as
// on the virtual one.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include "firmware/bundle_sink.hpp"
#include "firmware/checkerboard_corners.hpp"
#include "firmware/daemon/log.hpp"
#include "firmware/daemon/scan_service.hpp"
#include "firmware/daemon/scan_service_jobs.hpp"
#include "firmware/quasi_solve.hpp"
#include "firmware/stereo_solve.hpp"
#include "formats/atomic_file.hpp"
#include "formats/stereo_calibration.hpp"

namespace cylscan::firmware {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr const char* kSessionDir = "calibration-session";

// The mean of each camera's frames, in the frames' own type.
class FrameMeanSink final : public FrameSink {
 public:
  void onFrame(std::string_view camera, FringeSet /*set*/, int /*k*/, double /*stage_deg*/,
               const cv::Mat& image) override {
    Mean& m = means_[std::string(camera)];
    if (m.count == 0) {
      m.type = image.type();
      image.convertTo(m.sum, CV_64F);
    } else {
      cv::Mat f;
      image.convertTo(f, CV_64F);
      m.sum += f;
    }
    ++m.count;
  }

  cv::Mat mean(const std::string& camera) const {
    const auto it = means_.find(camera);
    if (it == means_.end() || it->second.count == 0)
      throw ScanError("camera " + camera + " gave no frame");
    cv::Mat out;
    it->second.sum.convertTo(out, it->second.type, 1.0 / it->second.count);
    return out;
  }

 private:
  struct Mean {
    cv::Mat sum;
    int type = 0;
    int count = 0;
  };
  std::map<std::string, Mean, std::less<>> means_;
};

formats::CheckerboardInfo boardOf(const json& body) {
  formats::CheckerboardInfo board{9, 6, 12.0};  // the virtual head's target
  if (body.is_null()) return board;
  if (!body.is_object()) throw ServiceError(400, "the body must be a JSON object");
  for (const auto& [key, value] : body.items())
    if (key != "board") throw ServiceError(400, key + ": not an option of a session (board)");
  if (!body.contains("board")) return board;
  const json& b = body.at("board");
  const auto integer = [&](const char* key, int lo, int hi) {
    if (!b.is_object() || !b.contains(key) || !b.at(key).is_number_integer() ||
        b.at(key).get<int>() < lo || b.at(key).get<int>() > hi)
      throw ServiceError(400, std::string("board.") + key + ": must be an integer from " +
                                  std::to_string(lo) + " to " + std::to_string(hi) +
                                  " (inner corners)");
    return b.at(key).get<int>();
  };
  board.cols = integer("cols", 3, 50);
  board.rows = integer("rows", 3, 50);
  if (!b.contains("square_mm") || !b.at("square_mm").is_number() ||
      !(b.at("square_mm").get<double>() > 0) || b.at("square_mm").get<double>() > 500)
    throw ServiceError(400, "board.square_mm: must be a number in (0, 500]");
  board.square_mm = b.at("square_mm").get<double>();
  return board;
}

}  // namespace

std::optional<std::string> sceneOf(const json& body) {
  if (!body.is_object()) throw ServiceError(400, "the body must be a JSON object");
  for (const auto& [key, value] : body.items())
    if (key != "scene") throw ServiceError(400, key + ": not an option of a capture (scene)");
  if (!body.contains("scene")) return std::nullopt;
  if (!body.at("scene").is_string()) throw ServiceError(400, "scene: must be a string");
  return body.at("scene").get<std::string>();
}

void ScanService::loadSession() {
  const auto& main = profile_.camera("main").config;
  session_ = CalibrationSession::load(options_.data_dir / kSessionDir, {main.width, main.height});
}

void ScanService::requireTwoCameras() const {
  for (const char* name : {"main", "aux"}) {
    const bool known = std::any_of(profile_.cameras.begin(), profile_.cameras.end(),
                                   [&](const drivers::CameraProfile& c) { return c.name == name; });
    if (!known)
      throw ServiceError(409, "the board " + board_name_ + " has no camera '" + name +
                                  "': a calibration session needs main and aux");
  }
}

json ScanService::startSession(const json& body) {
  const formats::CheckerboardInfo board = boardOf(body);
  requireTwoCameras();
  // The answer is the session as GET gives it, with the virtual head's targets.
  std::optional<json> targets;
  if (profile_.sim) targets = calibrationTargets();
  std::lock_guard lock(mutex_);
  if (stopping_) throw ServiceError(503, "the daemon is stopping");
  if (job_ && job_->request.capture)
    throw ServiceError(409, "a calibration capture is running; the session stays until it ends");
  if (session_ && session_->state().state == "solving")
    throw ServiceError(409, "the session is solving; start a new one once it ends");
  const auto& main = profile_.camera("main").config;
  session_ =
      CalibrationSession::create(options_.data_dir / kSessionDir, board, {main.width, main.height},
                                 isoTime(std::chrono::system_clock::now()));
  logInfo("calibration session started");
  json out = session_->describe();
  events_.publish("calibration", out);
  if (targets) out["targets"] = std::move(*targets);
  return out;
}

std::optional<json> ScanService::session() const {
  std::optional<json> out;
  {
    std::lock_guard lock(mutex_);
    if (!session_) return std::nullopt;
    out = session_->describe();
  }
  if (profile_.sim) (*out)["targets"] = calibrationTargets();
  return out;
}

json ScanService::calibrationTargets() const {
  json targets = {{"boards", json::array()}, {"planes", json::array()}};
  std::vector<std::string> boards, planes;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(scenes_dir_ / "calibration", ec)) {
    const std::string name = entry.path().filename().string();
    if (!name.ends_with(".toml")) continue;
    if (name.starts_with("board")) boards.push_back("calibration/" + name);
    if (name.starts_with("plane")) planes.push_back("calibration/" + name);
  }
  std::sort(boards.begin(), boards.end());
  std::sort(planes.begin(), planes.end());
  for (const auto& b : boards)
    targets["boards"].push_back(b);
  for (const auto& p : planes)
    targets["planes"].push_back(p);
  return targets;
}

std::shared_ptr<CalibrationSession> ScanService::capturingSessionLocked() const {
  if (!session_)
    throw ServiceError(404, "no calibration session: POST /api/v1/calibration/session");
  const std::string state = session_->state().state;
  if (state == "solving") throw ServiceError(409, "the session is solving");
  return session_;
}

ScanService::Request ScanService::captureRequest(const json& body) const {
  const std::optional<std::string> scene = sceneOf(body);
  json options = json::object();
  if (scene) options["scene"] = *scene;
  Request request = validate(options);
  request.scan.cameras = {"main", "aux"};
  request.save_bundle = false;
  return request;
}

std::future<json> ScanService::captureBoard(const json& body) {
  Request request = captureRequest(body);
  auto promise = std::make_shared<std::promise<json>>();
  std::future<json> reply = promise->get_future();
  std::lock_guard lock(mutex_);
  refuseUnlessIdleLocked();
  SessionCapture capture;
  capture.session = capturingSessionLocked();
  capture.board_reply = std::move(promise);
  request.capture = std::move(capture);
  queueCaptureLocked(std::move(request));
  return reply;
}

json ScanService::capturePlane(const json& body) {
  Request request = captureRequest(body);
  request.save_bundle = true;
  requireFreeSpace(estimateBytes(request) + options_.free_space_margin_bytes);
  std::lock_guard lock(mutex_);
  refuseUnlessIdleLocked();
  SessionCapture capture;
  capture.session = capturingSessionLocked();
  std::optional<std::string> scene;
  if (body.contains("scene")) scene = body.at("scene").get<std::string>();
  capture.plane_index = capture.session->beginPlane(scene);
  const int index = capture.plane_index;
  request.capture = std::move(capture);
  queueCaptureLocked(std::move(request));
  events_.publish("calibration", session_->describe());
  return {{"index", index}};
}

void ScanService::queueCaptureLocked(Request request) {
  auto job = std::make_unique<Job>();
  job->request = std::move(request);
  job->record.id = newScanId(std::chrono::system_clock::now());
  job->record.frames = job->request.frames_total;
  job_ = std::move(job);
  publishState();
  cv_.notify_all();
}

void ScanService::runSessionCapture(Job& job) {
  SessionCapture& capture = *job.request.capture;
  CalibrationSession& session = *capture.session;
  const bool board_pair = capture.board_reply != nullptr;
  std::optional<json> board_reply;
  std::exception_ptr failure;
  std::optional<std::string> plane_error;
  try {
    if (stopping()) throw ScanError("aborted: daemon stopping");
    if (!board_ || !acquisition_ || job.request.scene != board_scene_)
      reopenBoard(job.request.scene);
    const ScanPlan plan = planScan(job.request.scan, board_->profile().stage);
    const auto progress = [&](const ScanProgress& p) { onProgress(job, p); };
    const std::optional<std::string> scene =
        job.request.given.contains("scene")
            ? std::optional<std::string>(job.request.given["scene"].get<std::string>())
            : std::nullopt;
    if (board_pair) {
      FrameMeanSink mean;
      acquisition_->run(job.request.scan, plan, mean, progress);
      const PairDetection found =
          detectPairCorners(session.board(), mean.mean("main"), mean.mean("aux"));
      SessionBoard board;
      board.found_main = found.main.has_value();
      board.found_aux = found.aux.has_value();
      board.scene = scene;
      if (found.found()) {
        board.main = *found.main;
        board.aux = *found.aux;
      }
      const int index = session.addBoard(std::move(board));
      board_reply =
          json{{"index", index},
               {"found", {{"main", found.main.has_value()}, {"aux", found.aux.has_value()}}}};
      logInfo("calibration board " + std::to_string(index) +
              (found.found() ? ": found in both cameras" : ": not found in " + found.missing()));
    } else {
      const fs::path dir = session.planeDir(capture.plane_index);
      fs::path partial = dir;
      partial += ".partial";
      std::error_code ec;
      fs::remove_all(partial, ec);
      fs::remove_all(dir, ec);
      BundleSink bundle(partial, plan, job.request.scan.cameras, bundleExtra(job.request));
      acquisition_->run(job.request.scan, plan, bundle, progress);
      bundle.commit();
      syncTree(partial);
      fs::rename(partial, dir);
      formats::syncDirectory(dir.parent_path());
      logInfo("calibration plane " + std::to_string(capture.plane_index) + " captured");
    }
  } catch (const ServiceError&) {
    failure = std::current_exception();
  } catch (const std::exception& e) {
    logError(std::string("calibration capture failed: ") + e.what());
    failure =
        std::make_exception_ptr(ServiceError(503, std::string("the capture failed: ") + e.what()));
    plane_error = e.what();
  }
  if (!board_pair) {
    try {
      session.finishPlane(capture.plane_index, plane_error);
    } catch (const std::exception& e) {
      logError(std::string("calibration session not saved: ") + e.what());
    }
  }
  if (board_pair) {
    if (failure) {
      capture.board_reply->set_exception(failure);
    } else {
      capture.board_reply->set_value(*board_reply);
    }
  }
  std::lock_guard lock(mutex_);
  job_.reset();
  if (session_.get() == &session) events_.publish("calibration", session.describe());
  publishState();
  cv_.notify_all();
}

void ScanService::solveSession() {
  std::shared_ptr<CalibrationSession> s;
  {
    std::lock_guard lock(mutex_);
    if (stopping_) throw ServiceError(503, "the daemon is stopping");
    s = capturingSessionLocked();
    if (job_ && job_->request.capture)
      throw ServiceError(409, "a calibration capture is running; solve once it ends");
    const std::size_t boards = s->keptBoards().size();
    const std::size_t planes = s->donePlanes().size();
    const StereoSolveOptions stereo;
    const QuasiSolveOptions quasi;
    if (static_cast<int>(boards) < stereo.min_pairs)
      throw ServiceError(409, "too few checkerboard pairs: " + std::to_string(boards) +
                                  " found in both cameras, " + std::to_string(stereo.min_pairs) +
                                  " needed");
    if (static_cast<int>(planes) < quasi.min_poses)
      throw ServiceError(409, "too few plane poses: " + std::to_string(planes) + " captured, " +
                                  std::to_string(quasi.min_poses) + " needed");
    s->setSolving();
    events_.publish("calibration", s->describe());
  }
  if (solve_thread_.joinable()) solve_thread_.join();  // the last solve has ended
  solve_thread_ = std::thread([this, s] { runSolve(s); });
}

void ScanService::runSolve(const std::shared_ptr<CalibrationSession>& s) {
  auto last_event = std::chrono::steady_clock::now();
  const SolveProgress progress = [&](double done) {
    if (stopping()) throw std::runtime_error("the daemon stopped during the solve");
    s->setProgress(done);
    const auto now = std::chrono::steady_clock::now();
    if (now - last_event < std::chrono::milliseconds(200)) return;
    last_event = now;
    std::lock_guard lock(mutex_);
    events_.publish("calibration_progress", {{"state", "solving"}, {"progress", done}});
  };
  try {
    StereoCorners corners;
    const auto& main = profile_.camera("main").config;
    corners.image_size = {main.width, main.height};
    for (const SessionBoard& b : s->keptBoards())
      corners.pairs.push_back({std::to_string(b.index), b.main, b.aux});
    corners.pair_count = corners.pairs.size();
    ProgressSpan whole(progress, 0, 1);
    const StereoSolveResult stereo = solveStereo(s->board(), corners, {}, whole.part(0, 0.05));
    formats::writeStereoCalibration(s->stereoFile(), stereo.calibration);
    QuasiSolveOptions options;
    options.phase = validate(json::object()).phase_default;
    std::vector<SessionPlane> planes = s->donePlanes();
    std::vector<fs::path> bundles;
    bundles.reserve(planes.size());
    for (const SessionPlane& p : planes)
      bundles.push_back(s->planeDir(p.index));
    const QuasiSolveResult quasi =
        solveQuasiCalibration(stereo.calibration, bundles, options, whole.part(0.05, 1));
    formats::writeFileAtomically(s->calibrationFile(), quasi.calibration.serialize());
    const auto camera = [](const StereoCameraResult& c) {
      return json{
          {"rms_px", c.rms_px},
          {"fx", c.camera_matrix(0, 0)},
          {"fy", c.camera_matrix(1, 1)},
          {"cx", c.camera_matrix(0, 2)},
          {"cy", c.camera_matrix(1, 2)},
          {"sigma_px",
           {{"fx", c.sigma.fx}, {"fy", c.sigma.fy}, {"cx", c.sigma.cx}, {"cy", c.sigma.cy}}}};
    };
    json poses = json::array();
    for (std::size_t i = 0; i < quasi.poses.size() && i < planes.size(); ++i) {
      planes[i].valid_fraction = quasi.poses[i].main_valid_fraction;
      planes[i].rmse_mm = quasi.poses[i].rmse_mm;
      json pose = quasiPoseJson(quasi.poses[i]);
      pose["index"] = planes[i].index;
      poses.push_back(std::move(pose));
    }
    json rejected = json::array();
    for (const Rejection& r : stereo.rejected)
      rejected.push_back({{"index", std::stoi(r.id)}, {"reason", r.reason}});
    const json result = {{"stereo_rms_px", stereo.stereo_rms_px},
                         {"boards_used", stereo.views.size()},
                         {"boards_rejected", std::move(rejected)},
                         {"pooled_rmse_mm", quasi.pooled_rmse_mm},
                         {"baseline_mm", stereo.baseline_mm},
                         {"cameras", {{"main", camera(stereo.main)}, {"aux", camera(stereo.aux)}}},
                         {"pixels_calibrated", quasi.calibration.validCount()},
                         {"poses", std::move(poses)}};
    s->setSolved(result, planes);
    logInfo("calibration solved: stereo RMS " + std::to_string(stereo.stereo_rms_px) +
            " px, pooled RMSE " + std::to_string(quasi.pooled_rmse_mm) + " mm");
  } catch (const std::exception& e) {
    logError(std::string("calibration solve failed: ") + e.what());
    try {
      s->setFailed(e.what());
    } catch (const std::exception& save) {
      logError(std::string("calibration session not saved: ") + save.what());
    }
  }
  std::lock_guard lock(mutex_);
  events_.publish("calibration", s->describe());
}

json ScanService::installSession() {
  std::shared_ptr<CalibrationSession> s;
  {
    std::lock_guard lock(mutex_);
    if (!session_)
      throw ServiceError(404, "no calibration session: POST /api/v1/calibration/session");
    s = session_;
  }
  if (s->state().state != "solved")
    throw ServiceError(409, "the session is " + s->state().state + ": solve it before installing");
  std::string bytes;
  {
    std::ifstream in(s->calibrationFile(), std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    bytes = text.str();
  }
  if (bytes.empty()) throw ServiceError(409, "the session's calibration is missing: solve again");
  return installCalibration("main", bytes);
}

json ScanService::rollbackCalibration() {
  std::lock_guard install(calibration_mutex_);
  const auto& c = profile_.camera("main").config;
  if (!store_.rollbackCalibration("main"))
    throw ServiceError(404, "no previous calibration is kept");
  const CalibrationDir installed = store_.calibrations();
  json info = json{{"installed", false}};
  try {
    if (auto calib = installed.calibration("main", {c.width, c.height}))
      info = calibrationInfoJson(*calib, fs::file_size(installed.calibrationFile("main")));
  } catch (const std::exception& e) {
    logWarn(std::string("the calibration rolled back to cannot be used: ") + e.what());
  }
  std::lock_guard lock(mutex_);
  if (info.value("installed", false)) {
    calibration_info_["main"] = info;
  } else {
    calibration_info_.erase("main");
  }
  logInfo("calibration of camera main rolled back");
  return info;
}

}  // namespace cylscan::firmware
