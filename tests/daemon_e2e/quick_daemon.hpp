// SPDX-License-Identifier: Apache-2.0
// A cylscand on the quick head of the fixture "quick_head"
// (tests/fixtures/quick_head.cmake): its own temporary data directory, a
// client bound to it, and the waits the tests share.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "daemon_process.hpp"
#include "http_client.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::test {

namespace fs = std::filesystem;
using nlohmann::json;
using test_support::TempDir;

inline fs::path quickFixture() {
  return CYLSCAN_QUICK_FIXTURE;
}
inline bool quickFixtureReady() {
  return fs::exists(quickFixture() / "ready");
}
inline std::string readBytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}
inline json quickTruth() {
  return json::parse(readBytes(quickFixture() / "truth.json"));
}
inline const std::string& quickCalibration() {
  static const std::string bytes = readBytes(quickFixture() / "calib.bin");
  return bytes;
}

struct DaemonSetup {
  explicit DaemonSetup(std::vector<std::string> extra = {}, bool calibrate = true,
                       std::string bearer = {})
      : extra_args(std::move(extra)), install_calibration(calibrate), token(std::move(bearer)) {}
  std::vector<std::string> extra_args;  // e.g. {"--token", "…"}
  bool install_calibration = true;      // PUT the fixture's calib.bin after the start
  std::string token;                    // sent by the client when installing the calibration
  // A program that runs cylscand (its path and the daemon's arguments follow
  // these), e.g. unshare to give it a small file system; an argument "{data}"
  // is replaced by the data directory.
  std::vector<std::string> wrapper;
  // A board folder instead of the fixture's (e.g. a copy with [faults]).
  fs::path board;
};

// Whether this machine lets a test mount a tmpfs in a mount namespace of
// its own (unshare), and the wrapper that runs cylscand with its data
// directory on a tmpfs of `size` (e.g. "1m") there.
inline bool canMountTmpfs() {
  TempDir probe;
  return fs::exists("/usr/bin/unshare") &&
         std::system(("/usr/bin/unshare --mount --propagation private /bin/sh -c 'mount -t tmpfs "
                      "-o size=1m tmpfs " +
                      probe.path().string() + "' >/dev/null 2>&1")
                         .c_str()) == 0;
}
inline std::vector<std::string> dataOnTmpfs(const std::string& size) {
  return {"/usr/bin/unshare",
          "--mount",
          "--propagation",
          "private",
          "/bin/sh",
          "-c",
          "mount -t tmpfs -o size=" + size + " tmpfs \"$0\" && exec \"$@\"",
          "{data}"};
}

// One daemon: `data` is its data directory (kept across restart()).
class QuickDaemon {
 public:
  explicit QuickDaemon(DaemonSetup setup = DaemonSetup()) : setup_(std::move(setup)) {
    if (!quickFixtureReady()) {
      throw std::runtime_error(quickFixture().string() +
                               "/ready is missing: run the test fixture.quick_head first "
                               "(ctest runs it for tests with FIXTURES_REQUIRED quick_head)");
    }
    fs::create_directories(data());
    start();
    if (setup_.install_calibration) {
      HttpClient::Headers h;
      if (!setup_.token.empty()) h.push_back("Authorization: Bearer " + setup_.token);
      const auto r = client().put("/api/v1/calibration", quickCalibration(), h);
      if (r.status != 200) {
        throw std::runtime_error("PUT /api/v1/calibration: " + r.describe() + stderrTail());
      }
    }
  }

  fs::path data() const { return dir_.path() / "data"; }
  const TempDir& dir() const { return dir_; }
  DaemonProcess& process() { return *process_; }
  HttpClient& client() { return *client_; }

  std::vector<std::string> args() const {
    const fs::path board = setup_.board.empty() ? quickFixture() / "board" : setup_.board;
    std::vector<std::string> a = {"--board",     board.string(), "--listen",
                                  "127.0.0.1:0", "--data",       data().string()};
    const fs::path web_root = CYLSCAN_WEB_ROOT;
    if (fs::is_directory(web_root)) {
      a.push_back("--web-root");
      a.push_back(web_root.string());
    }
    a.insert(a.end(), setup_.extra_args.begin(), setup_.extra_args.end());
    return a;
  }

  // The board of the next start() (empty: the fixture's).
  void setBoard(fs::path board) { setup_.board = std::move(board); }

  // A new process on the same data directory (the old one must be stopped).
  void start() {
    ++starts_;
    const fs::path log = dir_.path() / ("stderr-" + std::to_string(starts_) + ".txt");
    if (setup_.wrapper.empty()) {
      process_ = std::make_unique<DaemonProcess>(args(), log);
    } else {
      std::vector<std::string> a(setup_.wrapper.begin() + 1, setup_.wrapper.end());
      std::replace(a.begin(), a.end(), std::string("{data}"), data().string());
      a.push_back(kDaemonProgram.string());
      const auto own = args();
      a.insert(a.end(), own.begin(), own.end());
      process_ = std::make_unique<DaemonProcess>(a, log, setup_.wrapper.front());
    }
    client_ = std::make_unique<HttpClient>(process_->waitListening());
  }

  // Stops with SIGTERM and expects exit 0 within `timeout`.
  void stop(std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    const auto code = process_->terminate(timeout);
    EXPECT_TRUE(code.has_value()) << "cylscand did not stop within " << timeout.count()
                                  << " ms of SIGTERM" << stderrTail();
    if (code) {
      EXPECT_EQ(*code, 0) << "cylscand's exit code after SIGTERM" << stderrTail();
    }
  }

  std::string stderrTail() const {
    if (!process_) return {};
    const std::string text = process_->stderrText();
    return "\ncylscand stderr (last 3000 chars):\n" +
           (text.size() > 3000 ? text.substr(text.size() - 3000) : text);
  }

 private:
  DaemonSetup setup_;
  TempDir dir_;
  int starts_ = 0;
  std::unique_ptr<DaemonProcess> process_;
  std::unique_ptr<HttpClient> client_;
};

// POST /api/v1/scans; the id (empty, with a failure, when not 202).
inline std::string startScan(const HttpClient& client, const json& options = json::object()) {
  const auto r = client.postJson("/api/v1/scans", options);
  EXPECT_EQ(r.status, 202) << r.describe();
  const json j = r.json();
  if (r.status != 202 || !j.is_object() || !j.contains("id") || !j["id"].is_string()) return {};
  EXPECT_EQ(r.header("location"), "/api/v1/scans/" + j["id"].get<std::string>());
  return j["id"];
}

// Polls GET /api/v1/scans/{id} until the scan is done or failed (or the
// timeout); checks on the way that progress stays in [0, 1] and never falls.
inline json waitForScan(const HttpClient& client, const std::string& id,
                        std::chrono::seconds timeout = std::chrono::seconds(120)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  double last_progress = 0.0;
  json scan;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto r = client.get("/api/v1/scans/" + id);
    if (r.status != 200) {
      ADD_FAILURE() << "GET /api/v1/scans/" << id << ": " << r.describe();
      return json::object();
    }
    scan = r.json();
    const double progress = scan.value("progress", -1.0);
    EXPECT_GE(progress, 0.0) << scan.dump();
    EXPECT_LE(progress, 1.0) << scan.dump();
    EXPECT_GE(progress, last_progress) << "progress fell: " << scan.dump();
    last_progress = std::max(last_progress, progress);
    const std::string state = scan.value("state", "");
    if (state == "done" || state == "failed") return scan;
    EXPECT_TRUE(state == "queued" || state == "running") << scan.dump();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ADD_FAILURE() << "scan " << id << " not finished within " << timeout.count()
                << " s: " << scan.dump();
  return scan;
}

// Polls GET /api/v1/status until the daemon is idle again.
inline bool waitIdle(const HttpClient& client,
                     std::chrono::seconds timeout = std::chrono::seconds(60)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    const json s = client.get("/api/v1/status").json();
    if (s.is_object() && s.value("state", "") == "idle") return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

// waitForScan, then waitIdle: for tests whose next request needs the head
// free again (the scan's own "done" is checked by the scan tests). The scan
// as the daemon then reports it.
inline json finishScan(const HttpClient& client, const std::string& id) {
  json scan = waitForScan(client, id);
  EXPECT_TRUE(waitIdle(client)) << "the daemon is not idle after scan " << id;
  const auto r = client.get("/api/v1/scans/" + id);
  if (r.status == 200) scan = r.json();
  return scan;
}

}  // namespace cylscan::test
