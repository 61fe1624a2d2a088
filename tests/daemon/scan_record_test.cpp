// SPDX-License-Identifier: Apache-2.0
// The scan record's JSON (docs/http-api.md, "The scan object"): the keys and
// value types of each state byte for byte, read back to the same bytes,
// fields of the wrong type named, and a failed scan's error text whatever
// its job threw.
#include "firmware/daemon/scan_record.hpp"

#include <functional>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace cylscan::firmware {
namespace {

using nlohmann::json;

ScanRecord queued() {
  ScanRecord r;
  r.id = "20261201-160102-3f9a";
  r.created = "2026-12-01T16:01:02Z";
  r.options = {{"frames", 5}, {"mode", "stop"}};
  r.frames = 10;
  r.calibrated = true;
  return r;
}

AcquisitionFigures acquisition() {
  AcquisitionFigures a;
  a.retries = 1;
  a.homed = true;
  a.realtime = false;
  a.board_seconds = 38.25;
  a.warnings = {"slow camera"};
  a.step_jitter = {123040, 4.5, 21.0, 60.25};
  a.step_reramps = 2;
  a.trigger_jitter = {10, 3.0, 9.5, 11.0};
  a.time_split_s = {
      {"homing", 0.01}, {"travel", 9.5}, {"sets", 1.75}, {"settling", 0.0}, {"step_check", 0.0}};
  a.step_check = drivers::StepCheck{25, 26, true};
  a.peak_resident_bytes = 123456789;
  return a;
}

ScanRecord done() {
  ScanRecord r = queued();
  r.state = ScanState::kDone;
  r.progress = 1.0;
  r.finished = "2026-12-01T16:01:11Z";
  r.duration_s = 8.5;
  r.frames_done = 10;
  r.files = {"cloud.ply", "depth.tiff", "texture.png", "phase.png", "depth.png"};
  r.output =
      OutputFigures{PhaseSource::Fused, 0.625, algo::OrderResidual{-1.25, 0.0625, 1.5, 8000, 37},
                    std::size_t{12800}, std::nullopt};
  r.acquisition = acquisition();
  r.bundle = "bundle";
  return r;
}

// The record's JSON and the same read back from its text.
std::string bytesOf(const ScanRecord& r) {
  return json(r).dump();
}

void expectJson(const ScanRecord& r, const std::string& expected) {
  const json want = json::parse(expected);
  EXPECT_EQ(bytesOf(r), want.dump());
  // Read back from the text (as the store reads scan.json): the same bytes.
  EXPECT_EQ(bytesOf(json::parse(json(r).dump(2)).get<ScanRecord>()), want.dump());
}

TEST(ScanRecord, QueuedRunningAndFailedHaveTheirKeys) {
  ScanRecord r = queued();
  expectJson(r, R"({"id": "20261201-160102-3f9a", "state": "queued", "progress": 0.0,
    "created": "2026-12-01T16:01:02Z", "finished": null, "duration_s": null,
    "options": {"frames": 5, "mode": "stop"}, "frames": 10, "frames_done": 0, "files": [],
    "calibrated": true})");
  r.state = ScanState::kRunning;
  r.frames_done = 3;
  r.progress = 0.3;
  EXPECT_EQ(json(r)["state"], "running");
  r.state = ScanState::kFailed;
  r.error = "home switch never fired";
  r.finished = "2026-12-01T16:01:11Z";
  r.duration_s = 2.0;
  expectJson(r, R"({"id": "20261201-160102-3f9a", "state": "failed", "progress": 0.3,
    "created": "2026-12-01T16:01:02Z", "finished": "2026-12-01T16:01:11Z", "duration_s": 2.0,
    "options": {"frames": 5, "mode": "stop"}, "frames": 10, "frames_done": 3, "files": [],
    "calibrated": true, "error": "home switch never fired"})");
}

TEST(ScanRecord, ADoneScanAddsTheOutputsAndTheAcquisitionsFigures) {
  expectJson(done(), R"({"id": "20261201-160102-3f9a", "state": "done", "progress": 1.0,
    "created": "2026-12-01T16:01:02Z", "finished": "2026-12-01T16:01:11Z", "duration_s": 8.5,
    "options": {"frames": 5, "mode": "stop"}, "frames": 10, "frames_done": 10,
    "calibrated": true, "phase": "fused", "phase_valid_fraction": 0.625,
    "order_residual": {"centre_rad": -1.25, "spread_rad": 0.0625, "bound_rad": 1.5,
                       "samples": 8000, "decided_by_neighbours": 37},
    "files": ["cloud.ply", "depth.tiff", "texture.png", "phase.png", "depth.png"],
    "points": 12800,
    "retries": 1, "homed": true, "realtime": false, "board_seconds": 38.25,
    "warnings": ["slow camera"],
    "step_jitter": {"count": 123040, "p50_us": 4.5, "p99_us": 21.0, "max_us": 60.25},
    "step_reramps": 2,
    "trigger_jitter": {"count": 10, "p50_us": 3.0, "p99_us": 9.5, "max_us": 11.0},
    "board_seconds_split": {"homing": 0.01, "sets": 1.75, "settling": 0.0, "step_check": 0.0,
                            "travel": 9.5},
    "step_check": {"expected_edge": 25, "found_edge": 26, "lost_steps": 1, "passed": true},
    "peak_resident_bytes": 123456789,
    "bundle": "bundle"})");
  // Uncalibrated: no points.
  ScanRecord r = done();
  r.output->points.reset();
  r.bundle.reset();
  const json j = r;
  EXPECT_FALSE(j.contains("points"));
  EXPECT_FALSE(j.contains("bundle"));
}

TEST(ScanRecord, ARingScanAddsItsCamerasAndTheMergedCloud) {
  ScanRecord r = done();
  r.bundle.reset();
  RingOutput ring;
  ring.cameras = {{"main", true, 20480, PhaseSource::Fused, 0.5, "clouds/main.ply"},
                  {"cam90", false, 0, PhaseSource::Fused, 0.0, ""}};
  ring.cloud = MergedCloud::kMain;
  ring.cloud_note = "no head extrinsics installed (PUT /api/v1/head) for cam90";
  r.output->ring = ring;
  r.output->points = 20480;
  const json j = r;
  EXPECT_EQ(j["cameras"], json::parse(R"([
    {"camera": "main", "calibrated": true, "points": 20480, "phase": "fused",
     "phase_valid_fraction": 0.5, "file": "clouds/main.ply"},
    {"camera": "cam90", "calibrated": false, "points": 0}])"));
  EXPECT_EQ(j["cloud"], "main");
  EXPECT_EQ(j["cloud_note"], ring.cloud_note);
  EXPECT_EQ(bytesOf(json::parse(j.dump()).get<ScanRecord>()), j.dump());
  // Merged: no note.
  r.output->ring->cloud = MergedCloud::kMerged;
  r.output->ring->cloud_note.clear();
  EXPECT_FALSE(json(r).contains("cloud_note"));
  EXPECT_EQ(json(r)["cloud"], "merged");
}

TEST(ScanRecord, AnEarlierRecordWithoutLaterFieldsIsRead) {
  const ScanRecord r = json::parse(R"({"id": "20261201-160102-3f9a", "state": "done",
    "created": "2026-12-01T16:01:02Z", "files": ["texture.png", "phase.png"],
    "phase": "high", "phase_valid_fraction": 0.5, "retries": 0})")
                           .get<ScanRecord>();
  EXPECT_EQ(r.state, ScanState::kDone);
  EXPECT_EQ(r.files, (std::vector<std::string>{"texture.png", "phase.png"}));
  ASSERT_TRUE(r.output);
  EXPECT_EQ(r.output->phase, PhaseSource::High);
  EXPECT_FALSE(r.output->points);
  ASSERT_TRUE(r.acquisition);
  EXPECT_EQ(r.acquisition->step_reramps, 0);
  EXPECT_FALSE(r.finished);
}

TEST(ScanRecord, AFieldOfTheWrongTypeOrValueIsNamed) {
  const json good = done();
  const std::pair<const char*, json> cases[] = {
      {"id", json()},         {"id", 3},
      {"state", "paused"},    {"created", json::array()},
      {"frames", "ten"},      {"frames", 1e12},
      {"progress", "1"},      {"files", json::array({1})},
      {"options", "stop"},    {"phase", "low"},
      {"points", -1},         {"calibrated", 1},
      {"warnings", "none"},   {"step_jitter", json::array()},
      {"finished", 20261201}, {"cloud", "everything"},
  };
  for (const auto& [key, value] : cases) {
    json bad = good;
    bad[key] = value;
    try {
      (void)bad.get<ScanRecord>();
      ADD_FAILURE() << key << " = " << value.dump() << " was accepted";
    } catch (const ScanRecordError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(key, 0), 0u) << e.what();
    }
  }
  json missing = good;
  missing.erase("created");
  EXPECT_THROW((void)missing.get<ScanRecord>(), ScanRecordError);
  EXPECT_THROW((void)json::array().get<ScanRecord>(), ScanRecordError);
}

class Silent : public std::exception {
 public:
  const char* what() const noexcept override { return ""; }
};

std::string failureOf(const std::function<void()>& thrower) {
  try {
    thrower();
  } catch (...) {
    return failureText(std::current_exception());
  }
  return "(nothing thrown)";
}

TEST(ScanRecord, AFailedScanAlwaysSaysWhy) {
  EXPECT_EQ(failureOf([] { throw std::runtime_error("home switch never fired"); }),
            "home switch never fired");
  const std::string empty = failureOf([] { throw std::runtime_error(""); });
  EXPECT_NE(empty.find("std::runtime_error"), std::string::npos) << empty;
  EXPECT_NE(empty.find("without a message"), std::string::npos) << empty;
  const std::string silent = failureOf([] { throw Silent(); });
  EXPECT_NE(silent.find("Silent"), std::string::npos) << silent;
  const std::string blank = failureOf([] { throw std::logic_error(" \n"); });
  EXPECT_NE(blank.find("std::logic_error"), std::string::npos) << blank;
  const std::string other = failureOf([] { throw 42; });
  EXPECT_NE(other.find("not a std::exception"), std::string::npos) << other;
  EXPECT_FALSE(failureText(nullptr).empty());
}

}  // namespace
}  // namespace cylscan::firmware
