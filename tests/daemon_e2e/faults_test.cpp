// SPDX-License-Identifier: Apache-2.0
// Faults of the head under a running cylscand (docs/robustness.md, "Fault
// injection"). Each test makes one good scan on the fixture's board,
// restarts the daemon on the same data directory with a copy of the board
// whose head.toml has a [faults] table (docs/virtual-head.md: faults counted
// from the head's power-up), scans again and checks that the fault ends
// "cleanly": the scan is failed with a reason naming the fault (or, for a
// fault the transport cannot see, done and complete), the status gives the
// state and reason, the stage driver disabled and the light off, the earlier
// scan still whole, and the daemon still serving (a further scan).
// The full-disk, garbage-calibration and memory tests are at the end.
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool containsAny(const std::string& text, const std::vector<std::string>& words) {
  const std::string l = lower(text);
  return std::any_of(words.begin(), words.end(),
                     [&](const std::string& w) { return l.find(w) != std::string::npos; });
}

// A copy of the fixture's board folder in `dir` whose head.toml ends with
// `head_extra` (e.g. a [faults] table), paced to real time when asked.
fs::path boardWith(const TempDir& dir, const std::string& name, const std::string& head_extra,
                   bool pace_real_time = false) {
  const fs::path board = dir.path() / name;
  fs::copy(quickFixture() / "board", board, fs::copy_options::recursive);
  std::string head = readBytes(board / "head.toml");
  if (pace_real_time) {
    const std::string off = "pace_real_time = false";
    const auto at = head.find(off);
    if (at == std::string::npos) throw std::runtime_error("head.toml has no '" + off + "'");
    head.replace(at, off.size(), "pace_real_time = true");
  }
  std::ofstream out(board / "head.toml", std::ios::trunc);
  out << head << "\n" << head_extra << "\n";
  if (!out) throw std::runtime_error("cannot write " + (board / "head.toml").string());
  return board;
}

// Polls the status until it leaves "scanning" (idle or error).
bool waitNotScanning(const HttpClient& client,
                     std::chrono::seconds timeout = std::chrono::seconds(60)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    const json s = client.get("/api/v1/status").json();
    if (s.is_object() && s.value("state", "scanning") != "scanning") return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

const json kSmallScan = {{"frames", 5}, {"save_bundle", false}};

// The head's outputs in the status are safe: the stage driver disabled, the
// light off.
void expectSafeOutputs(const json& status, const std::string& what) {
  ASSERT_TRUE(status.contains("stage") && status["stage"].is_object()) << what << status.dump();
  EXPECT_EQ(status["stage"].value("enabled", true), false) << what << ": " << status.dump();
  EXPECT_EQ(status.value("light", true), false) << what << ": " << status.dump();
}

// One good scan on the fixture's board, then a restart on `faulty`.
class FaultedDaemon {
 public:
  explicit FaultedDaemon(const std::string& faults) {
    const std::string id = startScan(daemon_.client(), kSmallScan);
    const json scan = finishScan(daemon_.client(), id);
    if (scan.value("state", "") != "done")
      throw std::runtime_error("the good scan failed: " + scan.dump() + daemon_.stderrTail());
    good_id_ = id;
    good_cloud_ = daemon_.client().get("/api/v1/scans/" + id + "/cloud.ply").body;
    if (good_cloud_.empty()) throw std::runtime_error("the good scan has no cloud");
    daemon_.stop();
    daemon_.setBoard(boardWith(boards_, "faulty", faults));
    daemon_.start();
  }
  QuickDaemon& daemon() { return daemon_; }
  const HttpClient& client() { return daemon_.client(); }

  // The earlier scan is listed, done, and its cloud is byte for byte the same.
  void expectGoodScanKept() {
    const auto r = client().get("/api/v1/scans/" + good_id_);
    ASSERT_EQ(r.status, 200) << r.describe();
    EXPECT_EQ(r.json().value("state", ""), "done") << r.body;
    EXPECT_TRUE(client().get("/api/v1/scans/" + good_id_ + "/cloud.ply").body == good_cloud_)
        << "the earlier scan's cloud changed";
  }

  // Runs a scan into the fault: the scan as it ended and the status after it.
  std::pair<json, json> faultedScan(const json& options = kSmallScan) {
    const std::string id = startScan(client(), options);
    if (id.empty()) return {};
    const json scan = waitForScan(client(), id);
    EXPECT_TRUE(waitNotScanning(client())) << "still scanning after scan " << id;
    return {scan, client().get("/api/v1/status").json()};
  }

  // A failed scan: its reason names the fault (one of `words`), the status
  // is "error" with the same reason, the outputs are safe, the earlier scan
  // is kept and the scan itself is listed as failed after a restart too.
  void expectCleanFailure(const json& scan, const json& status,
                          const std::vector<std::string>& words) {
    EXPECT_EQ(scan.value("state", ""), "failed") << scan.dump() << daemon_.stderrTail();
    const std::string reason = scan.value("error", "");
    EXPECT_TRUE(containsAny(reason, words))
        << "the reason '" << reason << "' names none of the expected words" << daemon_.stderrTail();
    EXPECT_EQ(status.value("state", ""), "error") << status.dump();
    EXPECT_TRUE(status["last_error"].is_string() &&
                status["last_error"].get<std::string>().find(reason) != std::string::npos)
        << "last_error does not give the scan's reason: " << status.dump();
    expectSafeOutputs(status, "after the failed scan");
    expectGoodScanKept();
    const auto again = client().get("/api/v1/scans/" + scan.value("id", ""));
    EXPECT_EQ(again.status, 200) << again.describe();
    EXPECT_EQ(again.json().value("state", ""), "failed") << again.body;
    EXPECT_EQ(client().get("/api/v1/scans/" + scan.value("id", "") + "/cloud.ply").status, 404)
        << "a failed scan has no cloud";
  }

  // The daemon still serves: status, metrics, and (when the fault was one
  // shot) a scan that succeeds.
  void expectServing(bool next_scan_succeeds) {
    EXPECT_EQ(client().get("/api/v1/status").status, 200);
    EXPECT_EQ(client().get("/metrics").status, 200);
    const std::string id = startScan(client(), kSmallScan);
    ASSERT_FALSE(id.empty()) << daemon_.stderrTail();
    const json scan = finishScanAny(id);
    if (next_scan_succeeds) {
      EXPECT_EQ(scan.value("state", ""), "done") << scan.dump() << daemon_.stderrTail();
      EXPECT_EQ(scan.value("calibrated", false), true) << scan.dump();
      const json status = client().get("/api/v1/status").json();
      EXPECT_EQ(status.value("state", ""), "idle") << status.dump();
      EXPECT_EQ(status["last_error"], nullptr) << status.dump();
      expectSafeOutputs(status, "after the next scan");
    } else {
      EXPECT_EQ(scan.value("state", ""), "failed") << scan.dump();
    }
    EXPECT_TRUE(daemon_.process().running()) << daemon_.stderrTail();
  }

 private:
  json finishScanAny(const std::string& id) {
    waitForScan(client(), id);
    EXPECT_TRUE(waitNotScanning(client())) << "still scanning after scan " << id;
    return client().get("/api/v1/scans/" + id).json();
  }

  QuickDaemon daemon_;
  TempDir boards_;
  std::string good_id_;
  std::string good_cloud_;
};

// The status's stage and light are the lines as the firmware drives them:
// enabled and on while a scan has frames, disabled and off after it, the
// stage homed from the first scan on. (Every fault test below relies on them.)
TEST(DaemonFaults, StatusShowsTheOutputsAsDriven) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  const json idle = client.get("/api/v1/status").json();
  expectSafeOutputs(idle, "before any scan");
  EXPECT_EQ(idle["stage"].value("homed", true), false) << "homed before homing: " << idle.dump();
  const std::string id = startScan(client, {{"frames", 60}, {"save_bundle", false}});
  ASSERT_FALSE(id.empty());
  json during;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    const json scan = client.get("/api/v1/scans/" + id).json();
    if (scan.value("state", "") != "running" && scan.value("state", "") != "queued") break;
    if (scan.value("frames_done", 0) >= 1) {
      during = client.get("/api/v1/status").json();
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_TRUE(during.is_object()) << "the scan ended before the status could be read";
  // Still running when read (the status is read after a frame, before the last).
  EXPECT_EQ(during["stage"].value("enabled", false), true) << during.dump();
  EXPECT_EQ(during.value("light", false), true) << during.dump();
  const json scan = finishScan(client, id);
  EXPECT_EQ(scan.value("state", ""), "done") << scan.dump();
  const json after = client.get("/api/v1/status").json();
  expectSafeOutputs(after, "after the scan");
  EXPECT_EQ(after["stage"].value("homed", false), true) << after.dump();
  daemon.stop();
}

// A frame the camera exposes but never delivers: its wait times out, the
// frame is triggered again once (docs/architecture.md, "Faults") and the scan
// completes with every frame and the retry counted.
TEST(DaemonFaults, CameraDropsAFrameAndTheRetryRecovers) {
  FaultedDaemon d("[faults]\ndrop_frames = 1");
  const auto [scan, status] = d.faultedScan();
  EXPECT_EQ(scan.value("state", ""), "done") << scan.dump() << d.daemon().stderrTail();
  EXPECT_EQ(scan.value("frames_done", 0), scan.value("frames", -1)) << scan.dump();
  EXPECT_GE(scan.value("retries", 0), 1) << "the dropped frame was not retried: " << scan.dump();
  EXPECT_EQ(status.value("state", ""), "idle") << status.dump();
  expectSafeOutputs(status, "after the recovered scan");
  d.expectGoodScanKept();
  d.daemon().stop();
}

// Two frames in a row dropped: the retry is lost too and the scan fails
// naming the frame; one-shot, so the next scan is good.
TEST(DaemonFaults, CameraDropsTwoFramesAndTheScanFails) {
  FaultedDaemon d("[faults]\ndrop_frames = 2");
  const auto [scan, status] = d.faultedScan();
  d.expectCleanFailure(scan, status, {"twice", "sequence", "gap"});
  d.expectServing(/*next_scan_succeeds=*/true);
  d.daemon().stop();
}

// The first frame comes 10 s late (far past the frame timeout): the frame is
// triggered again once, and a camera that is still silent fails the scan.
TEST(DaemonFaults, CameraTimesOut) {
  FaultedDaemon d("[faults]\ndelay_first_frame_ms = 10000");
  const auto [scan, status] = d.faultedScan();
  d.expectCleanFailure(scan, status, {"timeout", "timed out", "no frame"});
  d.expectServing(/*next_scan_succeeds=*/true);
  d.daemon().stop();
}

// A torn transfer the transport does not flag (the lower half of a frame is
// garbage): the firmware cannot tell it from light, so the scan completes
// with every frame; what the fault must not do is crash, hang or lose data.
// The damaged scan shows it: fewer valid points than the clean one.
TEST(DaemonFaults, CameraDeliversACorruptFrame) {
  FaultedDaemon d("[faults]\ncorrupt_frames = 1");
  const auto [scan, status] = d.faultedScan();
  EXPECT_EQ(scan.value("state", ""), "done") << scan.dump() << d.daemon().stderrTail();
  EXPECT_EQ(scan.value("frames_done", 0), scan.value("frames", -1)) << scan.dump();
  EXPECT_EQ(status.value("state", ""), "idle") << status.dump();
  expectSafeOutputs(status, "after the scan with a corrupt frame");
  d.expectGoodScanKept();
  d.expectServing(/*next_scan_succeeds=*/true);
  // The clean scan after it against the damaged one.
  const json scans = d.client().get("/api/v1/scans").json();
  ASSERT_TRUE(scans.is_array() && scans.size() == 3u) << scans.dump();
  const int clean_points = scans[0].value("points", -1);
  const int damaged_points = scan.value("points", -1);
  EXPECT_GT(clean_points, 0) << scans[0].dump();
  EXPECT_LT(damaged_points, clean_points) << "the corrupt frame left no trace in the points";
  d.daemon().stop();
}

// A step pulse lost after homing (the first move of the scan): the motor
// stalls and the driver's fault output goes active, which fails the scan.
// The position is then unknown: the stage no longer counts as homed, and the
// next scan homes again and succeeds.
TEST(DaemonFaults, StageLosesSteps) {
  FaultedDaemon d("[faults]\nlose_steps_after = 3000\nlose_steps = 1");
  const auto [scan, status] = d.faultedScan();
  d.expectCleanFailure(scan, status, {"step", "stall", "fault"});
  EXPECT_EQ(status["stage"].value("homed", true), false)
      << "after lost steps the stage must not claim to be homed: " << status.dump();
  d.expectServing(/*next_scan_succeeds=*/true);
  d.daemon().stop();
}

// A home switch that never fires: homing gives up after its travel limit and
// the scan fails naming it; the head stays unusable (every scan fails the
// same way) but the daemon serves.
TEST(DaemonFaults, HomeSwitchNeverFires) {
  FaultedDaemon d("[faults]\nhome_switch = false");
  const auto [scan, status] = d.faultedScan();
  d.expectCleanFailure(scan, status, {"home"});
  EXPECT_EQ(status["stage"].value("homed", true), false) << status.dump();
  d.expectServing(/*next_scan_succeeds=*/false);
  d.daemon().stop();
}

// The calibration file replaced by garbage on disk while the daemon runs:
// the next scan fails before the head moves, naming the file, and the status
// shows the camera uncalibrated (docs/daemon.md, "Calibration"); a PUT of a
// good calibration makes scans work again.
TEST(DaemonFaults, CalibrationReplacedByGarbage) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  const std::string good_id = startScan(client, kSmallScan);
  ASSERT_EQ(finishScan(client, good_id).value("state", ""), "done") << daemon.stderrTail();
  const fs::path file = daemon.data() / "calibration" / "main.qcal";
  ASSERT_TRUE(fs::exists(file));
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out << "this is not a calibration any more";
  }
  const std::string id = startScan(client, kSmallScan);
  const json scan = waitForScan(client, id);
  ASSERT_TRUE(waitNotScanning(client));
  EXPECT_EQ(scan.value("state", ""), "failed") << scan.dump();
  EXPECT_NE(scan.value("error", "").find("calibration"), std::string::npos) << scan.dump();
  EXPECT_NE(scan.value("error", "").find("main.qcal"), std::string::npos) << scan.dump();
  const json status = client.get("/api/v1/status").json();
  EXPECT_EQ(status.value("state", ""), "error") << status.dump();
  EXPECT_EQ(status["calibration"].value("main", true), false) << status.dump();
  expectSafeOutputs(status, "after the scan refused for its calibration");
  EXPECT_EQ(client.get("/api/v1/scans/" + good_id).json().value("state", ""), "done");
  EXPECT_EQ(client.get("/api/v1/scans/" + good_id + "/cloud.ply").status, 200);
  // A good calibration again: scans are calibrated again.
  ASSERT_EQ(client.put("/api/v1/calibration", quickCalibration()).status, 200);
  EXPECT_EQ(client.get("/api/v1/status").json()["calibration"].value("main", false), true);
  const json next = finishScan(client, startScan(client, kSmallScan));
  EXPECT_EQ(next.value("state", ""), "done") << next.dump();
  EXPECT_EQ(next.value("calibrated", false), true) << next.dump();
  daemon.stop();
}

// The disk fills in the middle of writing a scan. The store refuses a scan
// whose estimate does not fit (507, tests/daemon_e2e/api_errors_test.cpp),
// and the estimate is an upper bound with a 16 MiB margin, so a file system
// merely sized too small never fills during a write: the fill comes from
// outside. The data directory is a 64 MiB tmpfs in the daemon's own mount
// namespace (the 507 test's unshare trick); the bundled scan of 60 frames
// takes seconds of rendering; once it has frames, the test fills the
// tmpfs through /proc/PID/root (the daemon's view of its mounts) until
// ENOSPC. The scan must fail naming the full disk, with its partial files
// gone, the earlier scan whole, the outputs safe; once the filler is gone a
// scan succeeds again.
TEST(DaemonFaults, DiskFillsWhileAScanIsWritten) {
  if (!canMountTmpfs()) GTEST_SKIP() << "no permission to mount a tmpfs in a mount namespace";
  DaemonSetup setup;
  setup.wrapper = dataOnTmpfs("64m");
  QuickDaemon daemon(std::move(setup));
  const HttpClient& client = daemon.client();
  const std::string good_id = startScan(client, kSmallScan);
  ASSERT_EQ(finishScan(client, good_id).value("state", ""), "done") << daemon.stderrTail();
  const std::string good_cloud = client.get("/api/v1/scans/" + good_id + "/cloud.ply").body;

  const std::string id = startScan(client, {{"frames", 60}, {"save_bundle", true}});
  ASSERT_FALSE(id.empty()) << daemon.stderrTail();
  // Wait for the first frames of the bundle, then fill the file system.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  json running;
  while (std::chrono::steady_clock::now() < deadline) {
    running = client.get("/api/v1/scans/" + id).json();
    const std::string state = running.value("state", "");
    if (running.value("frames_done", 0) >= 2 || (state != "running" && state != "queued")) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(running.value("state", ""), "running")
      << "the scan ended before the disk could fill: " << running.dump();
  const fs::path filler = fs::path("/proc") / std::to_string(daemon.process().pid()) / "root" /
                          daemon.data().relative_path() / "filler";
  {
    std::ofstream out(filler, std::ios::binary);
    ASSERT_TRUE(out) << "cannot write " << filler;
    const std::string block(1 << 20, 'f');
    for (int i = 0; i < 80 && out; ++i)
      out.write(block.data(), static_cast<std::streamsize>(block.size()));
    out.flush();
    // Fill to the last byte: smaller writes until ENOSPC.
    const std::string small(4096, 'f');
    for (int i = 0; i < 1024 && out; ++i)
      out.write(small.data(), static_cast<std::streamsize>(small.size()));
  }

  const json scan = waitForScan(client, id);
  ASSERT_TRUE(waitNotScanning(client));
  EXPECT_EQ(scan.value("state", ""), "failed") << scan.dump() << daemon.stderrTail();
  std::printf("[ reason   ] %s (after %d frames)\n", scan.value("error", "").c_str(),
              scan.value("frames_done", 0));
  EXPECT_TRUE(containsAny(scan.value("error", ""), {"no space", "enospc", "disk"}))
      << "the reason does not name the full disk: " << scan.dump();
  const json status = client.get("/api/v1/status").json();
  EXPECT_EQ(status.value("state", ""), "error") << status.dump();
  expectSafeOutputs(status, "after the disk filled");
  EXPECT_EQ(client.get("/api/v1/scans/" + id + "/cloud.ply").status, 404);
  EXPECT_TRUE(client.get("/api/v1/scans/" + good_id + "/cloud.ply").body == good_cloud)
      << "the earlier scan was damaged";
  // No partial directory left behind.
  const fs::path scans = filler.parent_path() / "scans";
  for (const auto& entry : fs::directory_iterator(scans))
    EXPECT_EQ(entry.path().filename().string().rfind(".partial-", 0), std::string::npos)
        << "left behind: " << entry.path();

  // Room again: the daemon scans again.
  fs::remove(filler);
  const std::string next = startScan(client, kSmallScan);
  ASSERT_FALSE(next.empty()) << daemon.stderrTail();
  EXPECT_EQ(finishScan(client, next).value("state", ""), "done") << daemon.stderrTail();
  daemon.stop();
}

}  // namespace
}  // namespace cylscan::test
