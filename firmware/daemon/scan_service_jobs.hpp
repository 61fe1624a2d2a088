// SPDX-License-Identifier: Apache-2.0
// ScanService's queued work, shared by the files that implement the service
// (scan_service.cpp, scan_service_checks.cpp, scan_service_session.cpp);
// nothing else includes it.
#pragma once

#include <chrono>
#include <filesystem>
#include <future>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "algo/quasi_calibration.hpp"
#include "firmware/daemon/calibration_session.hpp"
#include "firmware/daemon/scan_service.hpp"

namespace cylscan::firmware {

// ISO 8601 UTC to the second, as records give their times.
std::string isoTime(std::chrono::system_clock::time_point t);
// GET /api/v1/calibration's answer for an installed calibration.
nlohmann::json calibrationInfoJson(const algo::QuasiCalibration& calib, std::uintmax_t bytes);
// The `scene` of a capture's body (null or an object with no other key);
// ServiceError 400 naming what is wrong.
std::optional<std::string> sceneOf(const nlohmann::json& body);

// A capture of the calibration session, taken by the worker like a scan but
// kept in the session instead of the scan store.
struct SessionCapture {
  std::shared_ptr<CalibrationSession> session;
  // A checkerboard pair: its answer, once taken. Null for a plane pose.
  std::shared_ptr<std::promise<nlohmann::json>> board_reply;
  int plane_index = -1;  // a plane pose: its index in the session
};

// A fringe check, taken by the worker like a scan; its answer once taken.
struct FringeCheckCapture {
  std::shared_ptr<std::promise<nlohmann::json>> reply;
};

struct ScanService::Request {
  nlohmann::json given = nlohmann::json::object();
  ScanOptions scan;
  bool save_bundle = false;
  std::optional<PhaseSource> phase_asked;  // given in the POST
  PhaseSource phase_default = PhaseSource::Fused;
  std::optional<std::filesystem::path> scene;
  int frames_total = 0;
  std::optional<CheckRecord> check;       // the scan is a check of this artifact
  std::optional<SessionCapture> capture;  // not a scan: a capture of the calibration session
  std::optional<FringeCheckCapture> fringe_check;  // not a scan: a fringe check

  // A scan kept in the store (not a capture or a fringe check).
  bool isScan() const { return !capture && !fringe_check; }
};

struct ScanService::Job {
  Request request;
  ScanRecord record;  // mutex_ (the worker alone changes it)
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  std::optional<CheckRecord> check;  // mutex_, as record
};

}  // namespace cylscan::firmware
