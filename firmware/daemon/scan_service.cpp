// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/scan_service.hpp"

#include <time.h>

#include <algorithm>
#include <array>
#include <random>
#include <span>

#include "firmware/bundle_sink.hpp"
#include "firmware/daemon/log.hpp"
#include "firmware/daemon/scan_service_jobs.hpp"
#include "firmware/daemon/system_info.hpp"
#include "firmware/peak_memory.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/reconstruction.hpp"
#include "firmware/scan_output.hpp"
#include "firmware/scan_plan.hpp"
#include "formats/head_extrinsics.hpp"
#include "formats/input_error.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// What a scan's outputs take a pixel, at most: cloud.ply (xyz + 3 properties,
// 24 B), depth.tiff (4 B), texture.png (1 B), phase.png and depth.png (3 B each).
constexpr std::uint64_t kOutputBytesPerPixel = 36;
constexpr std::string_view kBundleDir = "bundle";  // a scan's raw frames, when kept

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

[[noreturn]] void badOption(const std::string& key, const std::string& fault) {
  throw ServiceError(400, key + ": " + fault);
}

// A scene as the API names it: a file in the board's scenes/ folder or in
// one folder below it (calibration/board07.toml); no segment starts with a
// dot, so nothing outside scenes/ can be named.
bool isSceneName(const std::string& name) {
  if (name.empty() || name.size() > 128) return false;
  std::size_t segments = 0;
  for (std::size_t begin = 0; begin <= name.size();) {
    const std::size_t end = std::min(name.find('/', begin), name.size());
    if (end == begin || name[begin] == '.' || ++segments > 2) return false;
    const bool plain = std::all_of(name.begin() + static_cast<std::ptrdiff_t>(begin),
                                   name.begin() + static_cast<std::ptrdiff_t>(end), [](char c) {
                                     return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                                            (c >= '0' && c <= '9') || c == '.' || c == '_' ||
                                            c == '-';
                                   });
    if (!plain) return false;
    begin = end + 1;
  }
  return true;
}

const std::vector<double>& durationBoundsSeconds() {
  static const std::vector<double> bounds = {1, 2, 5, 10, 20, 30, 60, 120, 300, 600};
  return bounds;
}

}  // namespace

std::string isoTime(std::chrono::system_clock::time_point t) {
  const std::time_t secs = std::chrono::system_clock::to_time_t(t);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  std::array<char, 32> buf{};
  std::strftime(buf.data(), buf.size(), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf.data();
}

json calibrationInfoJson(const algo::QuasiCalibration& calib, std::uintmax_t bytes) {
  return {{"installed", true},
          {"bytes", bytes},
          {"width", calib.size().width},
          {"height", calib.size().height},
          {"phase_source", toString(calib.info().phase_source)}};
}

ScanServiceOptions scanServiceOptions(const DaemonConfig& config, std::string version) {
  ScanServiceOptions o;
  o.board = config.board;
  o.data_dir = config.data_dir;
  o.retention = config.retention;
  o.scan = config.scan;
  o.max_calibration_bytes = config.max_calibration_bytes;
  o.update = config.update;
  o.version = std::move(version);
  return o;
}

ScanService::ScanService(ScanServiceOptions options)
    : options_(std::move(options)),
      store_(options_.data_dir),
      checks_(options_.data_dir),
      scan_duration_(durationBoundsSeconds()) {
  board_ = std::make_unique<drivers::Board>(drivers::Board::open(options_.board));
  profile_ = board_->profile();
  scan_profile_ = readScanProfile(profile_);
  board_name_ = profile_.name;
  scenes_dir_ = profile_.file.parent_path() / "scenes";
  acquisition_ = std::make_unique<Acquisition>(*board_);
  loadCameraSettings();
  scans_total_.inc("done", 0);
  scans_total_.inc("failed", 0);
  loadCalibrationInfo();
  loadHeadInfo();
  loadSession();
  UpdateOptions update;
  update.data_dir = options_.data_dir;
  update.max_bundle_bytes = options_.update.max_bundle_bytes;
  update.reboot = options_.update.reboot;
  update.reserve_bytes = options_.update_reserve_bytes;
  update.command_line = options_.command_line;
  update.boot_id = options_.boot_id;
  update_ = std::make_unique<UpdateService>(
      update, options_.installer,
      [this](const std::string& name, const json& data) { events_.publish(name, data); },
      [this] {
        std::lock_guard lock(mutex_);
        if (stopping_) throw ServiceError(503, "the daemon is stopping");
        if (job_) throw ServiceError(409, busyMessageLocked());
      });
  worker_ = std::thread([this] { worker(); });
}

ScanService::~ScanService() {
  stop();
}

void ScanService::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  live_.end(503, "the daemon is stopping");
  cv_.notify_all();
  // Acquisition::run clears an abort that comes before it starts, so the
  // abort is repeated until the worker has finished.
  for (;;) {
    {
      std::lock_guard lock(acquisition_mutex_);
      if (acquisition_) acquisition_->abort();
    }
    std::unique_lock lock(mutex_);
    if (cv_.wait_for(lock, std::chrono::milliseconds(20), [&] { return worker_done_; })) break;
  }
  if (worker_.joinable()) worker_.join();
  // A solve checks stopping_ at each step of its progress and ends.
  if (solve_thread_.joinable()) solve_thread_.join();
  if (update_) update_->stop();
  events_.close();
}

bool ScanService::waitUntilIdle(std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mutex_);
  return cv_.wait_for(lock, timeout, [&] { return !job_; });
}

void ScanService::loadCalibrationInfo() {
  const CalibrationDir installed = store_.calibrations();
  std::map<std::string, json, std::less<>> infos;
  for (const std::string& camera : board_->cameraNames()) {
    const auto& c = profile_.camera(camera).config;
    try {
      if (auto calib = installed.calibration(camera, {c.width, c.height}))
        infos[camera] =
            calibrationInfoJson(*calib, fs::file_size(installed.calibrationFile(camera)));
    } catch (const std::exception& e) {
      logWarn(std::string(e.what()) + "; not used");
    }
  }
  std::lock_guard lock(mutex_);
  calibration_info_ = std::move(infos);
}

void ScanService::loadHeadInfo() {
  try {
    if (const auto head = store_.calibrations().head()) {
      json info = json::parse(formats::headExtrinsicsJson(*head));
      std::lock_guard lock(mutex_);
      head_info_ = std::move(info);
    }
  } catch (const std::exception& e) {
    logWarn(std::string(e.what()) + "; not used");
  }
}

ScanService::Request ScanService::validate(const json& options) const {
  Request r;
  if (!options.is_null() && !options.is_object())
    throw ServiceError(400, "options: must be a JSON object");
  if (options.is_object()) r.given = options;
  static const std::array<std::string_view, 5> kKeys = {"mode", "frames", "save_bundle", "phase",
                                                        "scene"};
  for (const auto& [key, value] : r.given.items()) {
    if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end())
      badOption(key, "unknown option (known: mode, frames, save_bundle, phase, scene)");
  }
  r.scan = scanOptionsFrom(profile_, scan_profile_);
  r.save_bundle = options_.scan.save_bundle.value_or(scan_profile_.save_bundle);
  std::optional<std::string> mode = options_.scan.mode;
  std::optional<int> frames = options_.scan.frames;
  if (options_.scan.phase) r.phase_default = parsePhaseSource(*options_.scan.phase);

  if (r.given.contains("mode")) {
    const json& v = r.given["mode"];
    if (!v.is_string() || (v != "stop" && v != "continuous"))
      badOption("mode", "must be \"stop\" or \"continuous\"");
    mode = v.get<std::string>();
  }
  if (r.given.contains("frames")) {
    const json& v = r.given["frames"];
    if (!v.is_number_integer() || v.get<std::int64_t>() < 3 || v.get<std::int64_t>() > 1000)
      badOption("frames", "must be an integer from 3 to 1000");
    frames = v.get<int>();
  }
  if (r.given.contains("save_bundle")) {
    const json& v = r.given["save_bundle"];
    if (!v.is_boolean()) badOption("save_bundle", "must be true or false");
    r.save_bundle = v.get<bool>();
  }
  if (r.given.contains("phase")) {
    const json& v = r.given["phase"];
    if (!v.is_string() || (v != "fused" && v != "high"))
      badOption("phase", "must be \"fused\" or \"high\"");
    r.phase_asked = parsePhaseSource(v.get<std::string>());
  }
  if (r.given.contains("scene")) {
    const json& v = r.given["scene"];
    if (!profile_.sim) badOption("scene", "the board '" + board_name_ + "' is not a virtual head");
    if (!v.is_string() || !isSceneName(v.get<std::string>()))
      badOption("scene", "must name a file in the board's scenes/ folder or one folder below it");
    const fs::path file = scenes_dir_ / v.get<std::string>();
    std::error_code ec;
    if (!fs::is_regular_file(file, ec))
      badOption("scene", "no scene '" + v.get<std::string>() + "' in " + scenes_dir_.string());
    r.scene = file;
  }
  if (mode) r.scan.mode = *mode == "continuous" ? ScanMode::Continuous : ScanMode::StopAndGo;
  if (frames) r.scan.frames_high = r.scan.frames_low = *frames;
  // A ring plan (the 360° head) scans every camera of the board; a sets plan
  // scans main only (its sets are main's).
  if (r.scan.plan != PlanKind::Ring) r.scan.cameras = {"main"};
  try {
    const ScanPlan plan = planScan(r.scan, profile_.stage);
    r.frames_total = plan.frames();
  } catch (const std::invalid_argument& e) {
    badOption(r.given.contains("frames") ? "frames" : "options", e.what());
  }
  return r;
}

std::uint64_t ScanService::scanEstimateBytes(const json& options) const {
  return estimateBytes(validate(options));
}

std::uint64_t ScanService::estimateBytes(const Request& r) const {
  const auto& main = profile_.camera("main").config;
  const std::uint64_t pixels = static_cast<std::uint64_t>(std::max(main.width, 0)) *
                               static_cast<std::uint64_t>(std::max(main.height, 0));
  std::uint64_t bytes = pixels * kOutputBytesPerPixel + 65536;
  // A ring scan: each other camera's cloud twice (clouds/<camera>.ply and its
  // part of the merged cloud.ply, 25 B a point each).
  if (r.scan.cameras.size() > 1) bytes += pixels * 50 * (r.scan.cameras.size() - 1);
  if (r.save_bundle)
    bytes += static_cast<std::uint64_t>(r.frames_total) * pixels * (main.bit_depth > 8 ? 2 : 1);
  return bytes;
}

std::string ScanService::newScanId(std::chrono::system_clock::time_point now) {
  const std::time_t secs = std::chrono::system_clock::to_time_t(now);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  std::array<char, 32> stamp{};
  std::strftime(stamp.data(), stamp.size(), "%Y%m%d-%H%M%S", &tm);
  // The suffix is the millisecond (×64, plus a random 0..63), so ids made in
  // one second sort as they were made, by this process or an earlier one;
  // within this process they strictly increase.
  static thread_local std::mt19937 rng{std::random_device{}()};
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()) % 1000;
  unsigned suffix =
      static_cast<unsigned>(ms.count()) * 64 + std::uniform_int_distribution<unsigned>(0, 63)(rng);
  if (last_id_.starts_with(stamp.data()) && last_id_.size() == 20)
    suffix =
        std::max(suffix, static_cast<unsigned>(std::stoul(last_id_.substr(16), nullptr, 16)) + 1);
  for (;; ++suffix) {
    std::array<char, 8> hex{};
    std::snprintf(hex.data(), hex.size(), "%04x", std::min(suffix, 0xffffu));
    std::string id = std::string(stamp.data()) + "-" + hex.data();
    if (!store_.get(id)) {
      last_id_ = id;
      return id;
    }
    if (suffix >= 0xffffu) throw ServiceError(503, "too many scans in one second");
  }
}

json ScanService::stateJson() const {
  const std::string state = job_ ? "scanning" : last_error_ ? "error" : "idle";
  json out = {{"state", state},
              {"scan", job_ && job_->request.isScan() ? json(job_->record.id) : json(nullptr)}};
  if (job_ && job_->request.capture)
    out["capture"] = job_->request.capture->board_reply ? "calibration board" : "calibration plane";
  if (job_ && job_->request.fringe_check) out["capture"] = "fringe check";
  return out;
}

void ScanService::publishState() {
  events_.publish("state", stateJson());
}

std::string ScanService::startScan(const json& options) {
  // The plan and statvfs take a while (a ring plan: ~10^5 steps): they run
  // without mutex_ so status() never waits for them, and the refusals of a
  // busy or stopping head are checked again once they are done.
  std::optional<std::string> main_fitted_on;
  {
    std::lock_guard lock(mutex_);
    refuseUnlessIdleLocked();
    const auto it = calibration_info_.find("main");
    if (it != calibration_info_.end())
      main_fitted_on = it->second.at("phase_source").get<std::string>();
  }
  Request request = validate(options);
  if (request.phase_asked && main_fitted_on && *main_fitted_on != toString(*request.phase_asked))
    badOption("phase", "the installed calibration was fitted on the " + *main_fitted_on + " phase");
  requireFreeSpace(estimateBytes(request) + options_.free_space_margin_bytes);
  std::lock_guard lock(mutex_);
  refuseUnlessIdleLocked();
  return queueLocked(std::move(request));
}

void ScanService::refuseUnlessIdleLocked() const {
  if (stopping_) throw ServiceError(503, "the daemon is stopping");
  if (job_) throw ServiceError(409, busyMessageLocked());
  // UpdateService::begin claims first and asks after, so one of the two sees the other.
  if (update_ && update_->busy()) throw ServiceError(409, update_->busyMessage());
}

std::string ScanService::busyMessageLocked() const {
  if (job_->request.capture) return "a calibration capture is " + toString(job_->record.state);
  if (job_->request.fringe_check) return "a fringe check is " + toString(job_->record.state);
  return "scan " + job_->record.id + " is " + toString(job_->record.state);
}

void ScanService::requireFreeSpace(std::uint64_t need) const {
  try {
    const std::uint64_t free = store_.freeBytes();
    if (free < need)
      throw ServiceError(507, "no room on the disk for a scan: " + std::to_string(free) +
                                  " bytes free in " + store_.dataDir().string() + ", " +
                                  std::to_string(need) + " needed");
  } catch (const std::system_error& e) {
    logWarn(std::string("free space unknown: ") + e.what());
  }
}

std::string ScanService::queueLocked(Request request) {
  const auto now = std::chrono::system_clock::now();
  auto job = std::make_unique<Job>();
  job->request = std::move(request);
  ScanRecord& record = job->record;
  record.id = newScanId(now);
  record.created = isoTime(now);
  record.options = job->request.given;
  record.frames = job->request.frames_total;
  record.calibrated = calibration_info_.count("main") > 0;
  if (job->request.check) {
    job->check = job->request.check;
    job->check->id = record.id;
    job->check->created = record.created;
  }
  job_ = std::move(job);
  events_.publish("scan", job_->record);
  if (job_->check) events_.publish("check", *job_->check);
  publishState();
  logInfo("scan " + job_->record.id + " queued: " + job_->request.given.dump());
  cv_.notify_all();
  return job_->record.id;
}

// Scans when one is queued; else, while someone watches a camera, takes the
// live view's pictures. A queued scan waits at most for the picture being
// taken, and ends the live view before it starts.
void ScanService::worker() {
  for (;;) {
    Job* job = nullptr;
    std::optional<CameraControlSettings> changed;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock,
               [&] { return stopping_ || job_ || camera_settings_changed_ || live_.anyWatched(); });
      if (camera_settings_changed_) {
        changed = camera_settings_;
        camera_settings_changed_ = false;
      } else if (job_) {
        job = job_.get();
        job->record.state = ScanState::kRunning;
        job->started = Clock::now();
        if (job->request.isScan()) events_.publish("scan", job->record);
        if (job->check) {
          job->check->state = "running";
          events_.publish("check", *job->check);
        }
      } else if (stopping_) {
        break;  // nothing queued
      }
    }
    if (changed) {
      try {
        applyCameraSettings(*changed);
      } catch (const std::exception& e) {
        logError(std::string("cameras: the settings cannot be applied: ") + e.what());
      }
    } else if (job != nullptr) {
      live_.end(409, "a scan started");
      if (job->request.capture) {
        runSessionCapture(*job);
      } else if (job->request.fringe_check) {
        runFringeCheck(*job);
      } else {
        runJob(*job);  // ends with finishLocked()
      }
    } else {
      serveLiveView();
    }
  }
  std::lock_guard lock(mutex_);
  worker_done_ = true;
  cv_.notify_all();
}

// The old board is closed before the new one is opened (they share the
// lines), and neither is done under acquisition_mutex_: status() shows no
// stage meanwhile instead of waiting for the cameras to open.
void ScanService::reopenBoard(const std::optional<fs::path>& scene) {
  std::unique_ptr<Acquisition> old_acquisition;
  std::unique_ptr<drivers::Board> old_board;
  {
    std::lock_guard lock(acquisition_mutex_);
    old_acquisition = std::move(acquisition_);
    old_board = std::move(board_);
  }
  old_acquisition.reset();
  old_board.reset();
  auto board = std::make_unique<drivers::Board>(drivers::Board::open(options_.board, scene));
  auto acquisition = std::make_unique<Acquisition>(*board);
  {
    std::lock_guard lock(acquisition_mutex_);
    board_ = std::move(board);
    acquisition_ = std::move(acquisition);
    board_scene_ = scene;
  }
  CameraControlSettings settings;
  {
    std::lock_guard lock(mutex_);
    settings = camera_settings_;
  }
  applyCameraSettings(settings);
}

void ScanService::finishLocked(const ScanRecord& record) {
  job_.reset();
  events_.publish("scan", record);
  publishState();
  cv_.notify_all();
}

// Load, plan, acquire, write the outputs, record and commit; whatever is
// thrown on the way fails the scan. `job` is gone once it is finished.
void ScanService::runJob(Job& job) {
  const Request& request = job.request;
  std::optional<ScanRecord> done;
  ScanReport report;
  try {
    const fs::path partial = store_.beginScan(job.record.id);
    if (stopping()) throw ScanError("aborted: daemon stopping");
    if (!board_ || !acquisition_ || request.scene != board_scene_) reopenBoard(request.scene);
    const ScanCalibrations calibrations = loadCalibrations(request);
    const ScanPlan plan = planScan(request.scan, board_->profile().stage);
    PhaseSink phase(plan, phaseOptions());
    report = acquire(job, plan, phase, partial);
    ScanResult output =
        writeScanOutput(phase, calibrations, outputOptions(request, calibrations), partial);
    for (std::string& warning : output.warnings) {
      logWarn("scan " + job.record.id + ": " + warning);
      report.warnings.push_back(std::move(warning));
    }
    done = doneRecord(job, std::move(output), report);
    store_.commit(*done);
  } catch (...) {
    const std::string error = failureOf(std::current_exception());
    if (job.check) failCheck(job, error);
    finishFailed(job, error);
    return;
  }
  if (job.check) finishCheck(job, *done);
  finishDone(*done, report);
}

// The calibrations as installed now (a later install applies to later
// scans). Main's is read before the head moves: one replaced or damaged on
// disk since it was installed fails the scan rather than give no cloud.
ScanCalibrations ScanService::loadCalibrations(const Request& request) const {
  const auto& main = board_->profile().camera("main").config;
  ScanCalibrations calibrations;
  calibrations.main = store_.calibrations().calibration("main", {main.width, main.height});
  if (request.scan.cameras.size() > 1) calibrations.installed = store_.calibrations();
  return calibrations;
}

algo::PhaseOptions ScanService::phaseOptions() const {
  algo::PhaseOptions options;
  options.bit_depth = board_->profile().camera("main").config.bit_depth;
  return options;
}

// Main's phase is its calibration's, else the one asked for.
ScanOutputOptions ScanService::outputOptions(const Request& request,
                                             const ScanCalibrations& calibrations) const {
  ScanOutputOptions options;
  options.phase = calibrations.main ? calibrations.main->info().phase_source
                                    : request.phase_asked.value_or(request.phase_default);
  options.bit_depth = board_->profile().camera("main").config.bit_depth;
  if (request.scan.cameras.size() > 1) options.ring_cameras = request.scan.cameras;
  return options;
}

// The scan on the board: the phase folded and, when asked, the bundle kept.
json ScanService::bundleExtra(const Request& request) const {
  const auto& main = board_->profile().camera("main").config;
  json extra = {{"device", "cylscand " + board_name_},
                {"board", board_name_},
                {"mode", toString(request.scan.mode)},
                {"exposure_us", board_->camera("main").controls().exposure_us.value}};
  if (main.bit_depth > 8) extra["bit_depth"] = main.bit_depth;
  return extra;
}

ScanReport ScanService::acquire(Job& job, const ScanPlan& plan, PhaseSink& phase,
                                const fs::path& partial) {
  const Request& request = job.request;
  TeeSink sinks;
  sinks.add(phase);
  std::unique_ptr<BundleSink> bundle;
  if (request.save_bundle) {
    bundle = std::make_unique<BundleSink>(partial / kBundleDir, plan, request.scan.cameras,
                                          bundleExtra(request));
    sinks.add(*bundle);
  }
  logInfo("scan " + job.record.id + " running: " + std::to_string(plan.frames()) + " frames, " +
          std::string(toString(request.scan.mode)));
  ScanReport report = acquisition_->run(request.scan, plan, sinks,
                                        [&](const ScanProgress& p) { onProgress(job, p); });
  if (bundle) bundle->commit();
  return report;
}

void ScanService::onProgress(Job& job, const ScanProgress& p) {
  frames_total_.inc();
  std::lock_guard lock(mutex_);
  if (stopping_) acquisition_->abort();
  const double fraction =
      p.frames_total > 0 ? static_cast<double>(p.frames_done) / p.frames_total : 0.0;
  job.record.frames_done = p.frames_done;
  job.record.progress = fraction;
  events_.publish("progress", {{"id", job.record.id},
                               {"frames_done", p.frames_done},
                               {"frames_total", p.frames_total},
                               {"set", std::string(toString(p.set))},
                               {"progress", fraction}});
}

// The record as it will be stored: the job shows "running" until the scan
// is committed, so "done" is never seen before its files are there.
ScanRecord ScanService::doneRecord(const Job& job, ScanResult output,
                                   const ScanReport& report) const {
  ScanRecord record;
  {
    std::lock_guard lock(mutex_);
    record = job.record;
  }
  record.state = ScanState::kDone;
  record.progress = 1.0;
  record.frames_done = report.frames;
  record.files = std::move(output.files);
  record.calibrated = output.calibrated;
  record.output = std::move(output.figures);
  record.acquisition = acquisitionFigures(report);
  if (job.request.save_bundle) record.bundle = std::string(kBundleDir);
  record.finished = isoTime(std::chrono::system_clock::now());
  record.duration_s = secondsSince(job.started);
  return record;
}

void ScanService::finishDone(const ScanRecord& record, const ScanReport& report) {
  scans_total_.inc("done");
  scan_duration_.observe(*record.duration_s);
  retain(record.id);
  std::lock_guard lock(mutex_);
  step_jitter_ = report.step_jitter;
  trigger_jitter_ = report.trigger_jitter;
  time_split_ = report.split;
  realtime_ = report.realtime;
  if (record.output && record.output->order_residual.samples > 0)
    order_residual_ = record.output->order_residual;
  last_error_.reset();
  finishLocked(record);
  logInfo("scan " + record.id + " done in " + std::to_string(*record.duration_s) + " s");
}

// Recorded with its error and without files; when even that cannot be
// written, the partial dir goes and the scan is only reported.
void ScanService::finishFailed(const Job& job, const std::string& error) {
  ScanRecord record;
  {
    std::lock_guard lock(mutex_);
    record = job.record;
  }
  record.state = ScanState::kFailed;
  record.error = error;
  record.files.clear();
  record.finished = isoTime(std::chrono::system_clock::now());
  record.duration_s = secondsSince(job.started);
  try {
    store_.commit(record, /*keep_files=*/false);
  } catch (...) {
    logError("cannot record the failed scan " + record.id + ": " +
             failureText(std::current_exception()));
    store_.discard(record.id);
  }
  scans_total_.inc("failed");
  retain(record.id);
  std::lock_guard lock(mutex_);
  last_error_ = error;
  events_.publish("error", {{"id", record.id}, {"error", error}});
  finishLocked(record);
  logError("scan " + record.id + " failed: " + error);
}

// The error text of a failed scan. A calibration found unusable is shown
// uncalibrated in the status until it is installed again.
std::string ScanService::failureOf(const std::exception_ptr& failure) {
  try {
    std::rethrow_exception(failure);
  } catch (const UnusableCalibration& e) {
    if (!e.camera().empty()) {
      std::lock_guard lock(mutex_);
      calibration_info_.erase(e.camera());
    }
  } catch (...) {  // told below
  }
  return stopping() ? "aborted: daemon stopping" : failureText(failure);
}

// Retention once a scan is stored, before it is reported finished.
void ScanService::retain(const std::string& id) {
  try {
    store_.applyRetention(options_.retention, id);
  } catch (const std::exception& e) {
    logError(std::string("retention: ") + e.what());
  }
}

bool ScanService::stopping() const {
  std::lock_guard lock(mutex_);
  return stopping_;
}

// The board's cameras, whether each is scanned (ring plan: all; else main)
// and calibrated (mutex_ held).
json ScanService::camerasJsonLocked() const {
  json out = json::array();
  const bool ring = scan_profile_.plan == PlanKind::Ring;
  for (const auto& camera : profile_.cameras) {
    out.push_back({{"name", camera.name},
                   {"scanned", ring || camera.name == "main"},
                   {"calibrated", calibration_info_.count(camera.name) > 0}});
  }
  return out;
}

// Whether each of the board's cameras has a calibration installed (mutex_ held).
json ScanService::calibrationStateLocked() const {
  json out = json::object();
  for (const auto& camera : profile_.cameras)
    out[camera.name] = calibration_info_.count(camera.name) > 0;
  return out;
}

json ScanService::status() const {
  // The head's outputs as the firmware drives them (before mutex_: the two
  // mutexes are never held together).
  json stage = nullptr;
  json light = nullptr;
  {
    std::lock_guard lock(acquisition_mutex_);
    if (acquisition_) {
      const HeadOutputs o = acquisition_->outputs();
      stage = {{"enabled", o.stage_enabled}, {"homed", o.homed}, {"position_deg", o.position_deg}};
      light = o.light;
    }
  }
  // statvfs before mutex_ too: a slow file system holds up this answer only.
  const json disk_free = diskFreeBytes();
  std::lock_guard lock(mutex_);
  json s = stateJson();
  return {{"state", s["state"]},
          {"board", board_name_},
          {"version", options_.version},
          {"current_scan", s["scan"]},
          {"last_error", last_error_ ? json(*last_error_) : json(nullptr)},
          {"calibration", calibrationStateLocked()},
          {"cameras", camerasJsonLocked()},
          {"head", {{"installed", head_info_.has_value()}}},
          {"scans", store_.count()},
          {"uptime_s", secondsSince(started_)},
          {"realtime", realtime_},
          {"stage", stage},
          {"light", light},
          {"disk_free_bytes", disk_free}};
}

std::unique_ptr<UpdateUpload> ScanService::beginUpdate(std::uint64_t bytes) {
  return update_->begin(bytes);
}

json ScanService::system() const {
  json report = SystemInfo(options_.version, options_.data_dir, options_.command_line).report();
  report.update(update_->report());
  return report;
}

json ScanService::diskFreeBytes() const {
  try {
    return store_.freeBytes();
  } catch (const std::exception&) {
    return nullptr;  // unknown
  }
}

json ScanService::listScans() const {
  std::lock_guard lock(mutex_);
  json out = json::array();
  if (job_) out.push_back(job_->record);
  for (const ScanRecord& scan : store_.list())
    if (!job_ || scan.id != job_->record.id) out.push_back(scan);
  return out;
}

std::optional<json> ScanService::scan(std::string_view id) const {
  if (!isValidScanId(id)) return std::nullopt;
  {
    std::lock_guard lock(mutex_);
    if (job_ && job_->record.id == id) return job_->record;
  }
  const std::optional<ScanRecord> stored = store_.get(id);
  if (!stored) return std::nullopt;
  return *stored;
}

std::optional<fs::path> ScanService::scanFile(std::string_view id, std::string_view name) const {
  if (!isValidScanId(id)) return std::nullopt;
  {
    std::lock_guard lock(mutex_);
    if (job_ && job_->record.id == id) return std::nullopt;  // not done yet
  }
  return store_.file(id, name);
}

bool ScanService::deleteScan(std::string_view id) {
  if (!isValidScanId(id)) return false;
  {
    std::lock_guard lock(mutex_);
    if (job_ && job_->record.id == id) throw ServiceError(409, busyMessageLocked());
  }
  const bool removed = store_.remove(id);
  if (removed) logInfo("scan " + std::string(id) + " deleted");
  return removed;
}

json ScanService::installCalibration(std::string_view camera, std::string_view bytes) {
  const std::string name(camera);
  const auto known = std::find_if(profile_.cameras.begin(), profile_.cameras.end(),
                                  [&](const drivers::CameraProfile& c) { return c.name == name; });
  if (known == profile_.cameras.end())
    throw ServiceError(400, "camera: the board has no camera '" + name + "'");
  if (bytes.size() > options_.max_calibration_bytes)
    throw ServiceError(413, "calibration: " + std::to_string(bytes.size()) +
                                " bytes, more than max_calibration_bytes " +
                                std::to_string(options_.max_calibration_bytes));
  const auto span = std::as_bytes(std::span<const char>(bytes.data(), bytes.size()));
  std::optional<algo::QuasiCalibration> calib;
  try {
    calib = algo::QuasiCalibration::deserialize(span);
  } catch (const std::exception& e) {
    throw ServiceError(400, std::string("calibration: ") + e.what());
  }
  const auto& c = profile_.camera(name).config;
  try {
    calib->requireImageSize({c.width, c.height});
  } catch (const std::invalid_argument& e) {
    throw ServiceError(422,
                       std::string("calibration: ") + e.what() + " (board " + board_name_ + ")");
  }
  json info = calibrationInfoJson(*calib, bytes.size());
  {
    std::lock_guard install(calibration_mutex_);
    store_.installCalibration(name, span);
    std::lock_guard lock(mutex_);
    calibration_info_[name] = info;
  }
  logInfo("calibration of camera " + name + " installed (" + std::to_string(bytes.size()) +
          " bytes)");
  return info;
}

json ScanService::calibrationInfo(std::string_view camera) const {
  std::lock_guard lock(mutex_);
  auto it = calibration_info_.find(camera);
  if (it == calibration_info_.end()) return {{"installed", false}};
  return it->second;
}

std::optional<fs::path> ScanService::calibrationFile(std::string_view camera) const {
  {
    std::lock_guard lock(mutex_);
    if (calibration_info_.find(camera) == calibration_info_.end()) return std::nullopt;
  }
  const fs::path file = store_.calibrationPath(camera);
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return std::nullopt;
  return file;
}

json ScanService::installHead(std::string_view text) {
  formats::HeadExtrinsics head;
  try {
    head = formats::parseHeadExtrinsics(text, "head.json");
  } catch (const formats::InputError& e) {
    throw ServiceError(400, e.what());
  }
  if (head.frame != "main")
    throw ServiceError(422,
                       "head.json: \"frame\" must be main (the head frame), not " + head.frame);
  for (const auto& entry : head.cameras) {
    // Not a structured binding: clang 14 (bookworm) cannot capture one in a lambda.
    const std::string& camera = entry.first;
    const bool known =
        std::any_of(profile_.cameras.begin(), profile_.cameras.end(),
                    [&](const drivers::CameraProfile& c) { return c.name == camera; });
    if (!known) {
      std::string message = "head.json: \"cameras." + camera;
      message += "\": the board " + board_name_;
      message += " has no camera '" + camera + "'";
      throw ServiceError(422, message);
    }
  }
  const std::string canonical = formats::headExtrinsicsJson(head);
  json info = json::parse(canonical);
  {
    std::lock_guard install(calibration_mutex_);
    store_.installHead(canonical);
    std::lock_guard lock(mutex_);
    head_info_ = info;
  }
  logInfo("head extrinsics installed (" + std::to_string(head.cameras.size()) + " cameras)");
  return info;
}

std::optional<json> ScanService::headInfo() const {
  std::lock_guard lock(mutex_);
  return head_info_;
}

std::optional<fs::path> ScanService::scanCameraCloud(std::string_view id,
                                                     std::string_view camera) const {
  if (!isValidScanId(id)) return std::nullopt;
  {
    std::lock_guard lock(mutex_);
    if (job_ && job_->record.id == id) return std::nullopt;  // not done yet
  }
  return store_.cameraCloud(id, camera);
}

std::unique_ptr<EventStream> ScanService::subscribe() {
  std::lock_guard lock(mutex_);
  return events_.subscribe(HeadEvent{0, "state", stateJson()});
}

std::string ScanService::metricsText() const {
  MetricsWriter w;
  w.counter("cylscan_scans_total", "Scans finished, by result.", "result", scans_total_.values());
  w.histogram("cylscan_scan_duration_seconds", "Wall-clock time of a finished scan.",
              scan_duration_.snapshot());
  w.counter("cylscan_frames_total", "Frames captured by all scans.", frames_total_.value());
  std::optional<drivers::JitterStats::Snapshot> step, trigger;
  std::optional<algo::OrderResidual> residual;
  std::optional<ScanTimeSplit> split;
  {
    std::lock_guard lock(mutex_);
    step = step_jitter_;
    trigger = trigger_jitter_;
    residual = order_residual_;
    split = time_split_;
  }
  if (split) {
    w.gauge("cylscan_last_scan_board_seconds",
            "Where the last scan's time on the head's clock went.", "part",
            timeSplitSeconds(*split));
  }
  w.gauge("cylscan_peak_resident_bytes", "The daemon's peak resident memory (VmHWM).",
          static_cast<double>(peakResidentBytes()));
  const auto& bounds = defaultLatenessBoundsSeconds();
  w.histogram("cylscan_step_lateness_seconds",
              "Lateness of the step edges of the last scan's motion thread.",
              foldJitter(step.value_or(drivers::JitterStats::Snapshot{}), bounds));
  w.histogram("cylscan_trigger_lateness_seconds", "Lateness of the last scan's camera triggers.",
              foldJitter(trigger.value_or(drivers::JitterStats::Snapshot{}), bounds));
  w.gauge("cylscan_scans_stored", "Scans in the data directory.",
          static_cast<double>(store_.count()));
  if (residual) {
    w.gauge("cylscan_order_residual_centre_radians",
            "The last scan's order-residual centre: the low set's phase offset times -R.",
            residual->centre_rad);
    w.gauge("cylscan_order_residual_spread_radians",
            "The robust spread of the last scan's order residuals about their centre.",
            residual->spread_rad);
    w.gauge("cylscan_order_residual_bound_radians",
            "The residual bound beyond which the last scan's orders were not trusted.",
            residual->bound_rad);
    w.gauge("cylscan_order_residual_decided_by_neighbours",
            "Pixels of the last scan beyond the bound whose orders their neighbours decided.",
            static_cast<double>(residual->decided_by_neighbours));
  }
  return w.text();
}

}  // namespace cylscan::firmware
