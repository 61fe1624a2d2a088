// SPDX-License-Identifier: Apache-2.0
// The record of one scan: what GET /api/v1/scans/{id} answers, the "scan"
// events carry and scan.json stores (docs/http-api.md, "The scan object").
// Its JSON is written by to_json alone and read back by from_json (the store
// reading scan.json at startup).
#pragma once

#include <cstdint>
#include <exception>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "drivers/jitter_stats.hpp"
#include "firmware/acquisition.hpp"
#include "firmware/scan_output.hpp"

namespace cylscan::firmware {

enum class ScanState { kQueued, kRunning, kDone, kFailed };
std::string toString(ScanState state);

// The lateness of step edges or triggers, in microseconds.
struct JitterFigures {
  std::uint64_t count = 0;
  double p50_us = 0.0;
  double p99_us = 0.0;
  double max_us = 0.0;
};
JitterFigures jitterFigures(const drivers::JitterStats::Snapshot& snapshot);

// What the acquisition measured.
struct AcquisitionFigures {
  int retries = 0;  // frames taken again after a camera timeout
  bool homed = false;
  bool realtime = false;
  double board_seconds = 0.0;  // on the head's clock
  std::vector<std::string> warnings;
  JitterFigures step_jitter;
  std::int64_t step_reramps = 0;
  JitterFigures trigger_jitter;
  // Where the board time went (seconds): homing, travel, sets, settling, step_check.
  std::map<std::string, double> time_split_s;
  std::optional<drivers::StepCheck> step_check;
  std::uint64_t peak_resident_bytes = 0;  // the daemon's VmHWM when the scan ended
};
AcquisitionFigures acquisitionFigures(const ScanReport& report);

struct ScanRecord {
  std::string id;
  ScanState state = ScanState::kQueued;
  double progress = 0.0;                              // 0..1
  std::string created;                                // UTC, 2026-12-01T16:01:02Z
  std::optional<std::string> finished;                // once it ended
  std::optional<double> duration_s;                   // once it ended
  nlohmann::json options = nlohmann::json::object();  // as the POST gave them
  int frames = 0;                                     // of the plan
  int frames_done = 0;
  // Until the scan is done: whether main had a calibration installed when
  // it was queued; once done, whether one was used.
  bool calibrated = false;
  std::vector<std::string> files;  // a done scan's, by name

  std::optional<std::string> error;  // a failed scan's

  // A done scan's.
  std::optional<OutputFigures> output;
  std::optional<AcquisitionFigures> acquisition;
  std::optional<std::string> bundle;  // the folder of the raw frames, when kept

  bool finishedScan() const { return state == ScanState::kDone || state == ScanState::kFailed; }
};

// A scan.json (or scan object) that is not a scan record: the field and why.
class ScanRecordError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The scan object. Keys appear only when the state has them: `error` when
// failed, the output's and the acquisition's figures when done.
void to_json(nlohmann::json& j, const ScanRecord& record);
// Its inverse: `id`, `state` and `created` are required; a field written by
// an earlier version that lacks a later one takes the later one's default.
// ScanRecordError naming the field when one has the wrong type or value.
void from_json(const nlohmann::json& j, ScanRecord& record);

// The error text of a failed scan for what its job threw: the exception's
// message, or which exception it was when it has none, so that a failed
// scan always says something.
std::string failureText(const std::exception_ptr& failure);

}  // namespace cylscan::firmware
