// SPDX-License-Identifier: Apache-2.0
// The head as the daemon runs it (HeadService on a drivers::Board): one
// worker thread runs the scans one at a time through firmware::Acquisition,
// streams the phase, writes the outputs with the installed calibrations
// (firmware/scan_output.hpp) and commits each scan's record to the
// ScanStore; status, lists and events are snapshots taken under a short
// mutex, so no HTTP thread ever waits for the head, the plan or the disk.
//
// States: idle → scanning → idle, or error (status "last_error") after a
// failed scan until the next successful one. A scan is queued from startScan
// until the worker takes it, then running, then done or failed.
#pragma once

#include <chrono>
#include <condition_variable>
#include <exception>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "drivers/board.hpp"
#include "firmware/acquisition.hpp"
#include "firmware/daemon/calibration_session.hpp"
#include "firmware/daemon/camera_settings.hpp"
#include "firmware/daemon/check_store.hpp"
#include "firmware/daemon/daemon_config.hpp"
#include "firmware/daemon/event_hub.hpp"
#include "firmware/daemon/head_service.hpp"
#include "firmware/daemon/live_hub.hpp"
#include "firmware/daemon/metrics.hpp"
#include "firmware/daemon/scan_record.hpp"
#include "firmware/daemon/scan_store.hpp"
#include "firmware/daemon/update_service.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/scan_output.hpp"
#include "firmware/scan_profile.hpp"

namespace cylscan::firmware {

struct ScanServiceOptions {
  std::filesystem::path board;     // profile folder or board.toml
  std::filesystem::path data_dir;  // the ScanStore's
  RetentionConfig retention;
  ScanDefaults scan;  // defaults of POST options (absent: the profile's)
  std::uint64_t max_calibration_bytes = 134217728;
  std::uint64_t free_space_margin_bytes = 16u << 20;  // kept free beyond a scan's estimate
  std::string version = "0.0.0";
  UpdateConfig update;
  // The A/B updater (RAUC on an image); null: updates are 503.
  std::shared_ptr<UpdateInstaller> installer;
  // The update's free-space reserve and the files it reads the boot from (tests).
  std::uint64_t update_reserve_bytes = 32ull << 20;
  std::filesystem::path command_line = "/proc/cmdline";
  std::filesystem::path boot_id = "/proc/sys/kernel/random/boot_id";
};
ScanServiceOptions scanServiceOptions(const DaemonConfig& config, std::string version);

class ScanService final : public HeadService {
 public:
  // Opens the board (drivers::ConfigError / GpioError / CameraError as
  // drivers::Board::open), the acquisition and the data directory, and
  // starts the worker.
  explicit ScanService(ScanServiceOptions options);
  ~ScanService() override;  // stop()
  ScanService(const ScanService&) = delete;
  ScanService& operator=(const ScanService&) = delete;

  // Aborts the running scan (recorded failed, "aborted: daemon stopping"; the
  // stage disabled, the light off), fails a queued one, joins the worker and
  // closes the event streams. Later startScan calls get 503. Idempotent.
  void stop();

  const std::string& boardName() const { return board_name_; }
  const ScanStore& store() const { return store_; }
  // The board, for tests once stop() has returned (the worker owns it while running).
  drivers::Board* boardAfterStop() {
    std::lock_guard lock(mutex_);
    return worker_done_ ? board_.get() : nullptr;
  }
  // Waits until no scan is queued or running (tests, shutdown); false on timeout.
  bool waitUntilIdle(std::chrono::milliseconds timeout) const;
  // The bytes of free disk a scan of `options` asks for (outputs, the bundle
  // when saved) before the margin; ServiceError 400 for bad options.
  std::uint64_t scanEstimateBytes(const nlohmann::json& options) const;

  nlohmann::json status() const override;
  nlohmann::json system() const override;
  std::string startScan(const nlohmann::json& options) override;
  nlohmann::json listScans() const override;
  std::optional<nlohmann::json> scan(std::string_view id) const override;
  std::optional<std::filesystem::path> scanFile(std::string_view id,
                                                std::string_view name) const override;
  bool deleteScan(std::string_view id) override;
  nlohmann::json installCalibration(std::string_view camera, std::string_view bytes) override;
  nlohmann::json calibrationInfo(std::string_view camera) const override;
  std::optional<std::filesystem::path> calibrationFile(std::string_view camera) const override;
  nlohmann::json installHead(std::string_view text) override;
  std::optional<nlohmann::json> headInfo() const override;
  std::optional<std::filesystem::path> scanCameraCloud(std::string_view id,
                                                       std::string_view camera) const override;
  std::unique_ptr<EventStream> subscribe() override;
  std::unique_ptr<UpdateUpload> beginUpdate(std::uint64_t bytes) override;
  // Tests: the update's state machine.
  UpdateService& updates() { return *update_; }
  std::string metricsText() const override;
  nlohmann::json cameras() const override;
  nlohmann::json setCameraControls(std::string_view camera,
                                   const nlohmann::json& controls) override;
  std::unique_ptr<LiveStream> openLiveView(const LiveViewRequest& request) override;
  std::future<nlohmann::json> fringeCheck(const nlohmann::json& body) override;
  std::string fringePicture(std::string_view camera) const override;
  std::string startCheck(const nlohmann::json& request) override;
  nlohmann::json listChecks() const override;
  nlohmann::json startSession(const nlohmann::json& body) override;
  std::optional<nlohmann::json> session() const override;
  std::future<nlohmann::json> captureBoard(const nlohmann::json& body) override;
  nlohmann::json capturePlane(const nlohmann::json& body) override;
  void solveSession() override;
  nlohmann::json installSession() override;
  nlohmann::json rollbackCalibration() override;

 private:
  struct Request;  // a validated POST
  struct Job;      // the queued or running scan
  struct Calibration;

  // Checks the options and plans the scan; reads only what the constructor
  // set, so it needs no lock.
  Request validate(const nlohmann::json& options) const;
  std::uint64_t estimateBytes(const Request& request) const;
  void refuseUnlessIdleLocked() const;  // 503 stopping, 409 a scan queued or running
  std::string busyMessageLocked() const;
  void requireFreeSpace(std::uint64_t need) const;  // 507; statvfs, no lock
  std::string queueLocked(Request request);
  void worker();
  void reopenBoard(const std::optional<std::filesystem::path>& scene);
  void loadCalibrationInfo();
  void loadHeadInfo();

  // The cameras' controls (firmware/daemon/scan_service_cameras.cpp).
  void loadCameraSettings();
  // On the worker: configures the board's cameras with the settings and
  // reads back what they use and accept.
  void applyCameraSettings(const CameraControlSettings& settings);
  // On the worker, while no scan is queued: one exposure of the watched
  // cameras for the live view.
  void serveLiveView();
  nlohmann::json cameraJsonLocked(const drivers::CameraProfile& camera) const;

  // Checks (firmware/daemon/scan_service_checks.cpp): the artifact measured
  // on the scan just committed, or the check failed with its scan.
  void finishCheck(Job& job, const ScanRecord& done);
  void failCheck(Job& job, const std::string& error);
  // Adds a finished check to the history, the job and the event stream.
  void keepCheck(Job& job, const CheckRecord& check);

  // The fringe check (firmware/daemon/scan_service_fringes.cpp), on the worker.
  void runFringeCheck(Job& job);

  // The calibration session (firmware/daemon/scan_service_session.cpp).
  void loadSession();
  void requireTwoCameras() const;
  // The virtual head's target poses (scenes/calibration/boardNN, planeNN).
  nlohmann::json calibrationTargets() const;
  // The session that may take captures (mutex_ held): 404 none, 409 solving.
  std::shared_ptr<CalibrationSession> capturingSessionLocked() const;
  Request captureRequest(const nlohmann::json& body) const;
  void queueCaptureLocked(Request request);
  void runSessionCapture(Job& job);                                   // on the worker
  void runSolve(const std::shared_ptr<CalibrationSession>& session);  // on solve_thread_

  // One scan, on the worker: the steps of runJob.
  void runJob(Job& job);
  ScanCalibrations loadCalibrations(const Request& request) const;
  algo::PhaseOptions phaseOptions() const;
  ScanOutputOptions outputOptions(const Request& request,
                                  const ScanCalibrations& calibrations) const;
  // capture.json's extra fields of a bundle the worker writes (on the worker).
  nlohmann::json bundleExtra(const Request& request) const;
  ScanReport acquire(Job& job, const ScanPlan& plan, PhaseSink& phase,
                     const std::filesystem::path& partial);
  void onProgress(Job& job, const ScanProgress& progress);
  ScanRecord doneRecord(const Job& job, ScanResult output, const ScanReport& report) const;
  void finishDone(const ScanRecord& record, const ScanReport& report);
  void finishFailed(const Job& job, const std::string& error);
  std::string failureOf(const std::exception_ptr& failure);
  void retain(const std::string& id);
  bool stopping() const;

  void publishState();  // mutex_ held
  // The job's end (mutex_ held): no job, its last scan event, the state.
  void finishLocked(const ScanRecord& record);
  nlohmann::json stateJson() const;  // mutex_ held
  nlohmann::json camerasJsonLocked() const;
  nlohmann::json calibrationStateLocked() const;
  nlohmann::json diskFreeBytes() const;  // null when unknown
  std::string newScanId(std::chrono::system_clock::time_point now);

  ScanServiceOptions options_;
  drivers::BoardProfile profile_;  // as opened (the default scene)
  ScanProfile scan_profile_;       // its [scan], read when the service starts
  std::string board_name_;
  std::filesystem::path scenes_dir_;
  ScanStore store_;
  CheckStore checks_;
  EventHub events_;
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();

  // The worker's own: the board and its acquisition (swapped for another scene).
  std::unique_ptr<drivers::Board> board_;
  std::optional<std::filesystem::path> board_scene_;
  mutable std::mutex acquisition_mutex_;  // guards acquisition_ against abort(), status()
  std::mutex calibration_mutex_;          // one calibration install at a time
  std::unique_ptr<Acquisition> acquisition_;

  mutable std::mutex mutex_;
  mutable std::condition_variable cv_;
  std::unique_ptr<Job> job_;  // queued or running
  bool stopping_ = false;
  bool worker_done_ = false;
  std::optional<std::string> last_error_;
  bool realtime_ = false;
  std::optional<algo::OrderResidual> order_residual_;  // the last done scan's
  std::string last_id_;
  std::map<std::string, nlohmann::json, std::less<>>
      calibration_info_;                     // by camera, when installed
  std::optional<nlohmann::json> head_info_;  // the installed head.json
  CameraControlSettings camera_settings_;    // as set through the API
  bool camera_settings_changed_ = false;     // not yet applied by the worker
  std::map<std::string, drivers::CameraControls, std::less<>> camera_controls_;  // as applied
  std::mutex settings_file_mutex_;  // one writer of cameras.json at a time
  LiveHub live_;
  std::map<std::string, std::string, std::less<>> fringe_pictures_;  // mutex_; JPEG by camera
  std::shared_ptr<CalibrationSession> session_;  // mutex_ (the pointer; the session locks itself)
  std::thread solve_thread_;                     // the last solve's; joined by the next and stop()
  std::chrono::steady_clock::time_point last_live_capture_{};  // the worker's

  Counter frames_total_;
  LabelledCounter scans_total_;
  Histogram scan_duration_;
  std::optional<drivers::JitterStats::Snapshot> step_jitter_, trigger_jitter_;  // last scan
  std::optional<ScanTimeSplit> time_split_;                                     // last scan

  std::thread worker_;
  // Last: stopped (its install wait) before the events it publishes to close.
  std::unique_ptr<UpdateService> update_;
};

}  // namespace cylscan::firmware
