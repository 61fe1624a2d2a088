// SPDX-License-Identifier: Apache-2.0
// The error paths of the HTTP API (docs/http-api.md) on a running cylscand:
// unknown and invalid ids, paths that try to leave the data directory, bad
// JSON and bad options, bad and wrong-size calibrations (the installed one
// unchanged), size limits and wrong methods. Every error is a JSON
// {"error": "…"} body.
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "algo/quasi_calibration.hpp"
#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// The answer is an error with this status and a JSON body naming it.
void expectError(const HttpResponse& r, std::vector<long> statuses, const std::string& what,
                 const std::string& named = {}) {
  EXPECT_TRUE(std::find(statuses.begin(), statuses.end(), r.status) != statuses.end())
      << what << ": " << r.describe();
  EXPECT_FALSE(r.error().empty()) << what << ": not a JSON error body: " << r.body;
  if (!named.empty()) {
    EXPECT_NE(lower(r.error()).find(lower(named)), std::string::npos)
        << what << ": the error does not name '" << named << "': " << r.error();
  }
  EXPECT_EQ(r.header("access-control-allow-origin"), "") << what << ": CORS must be off";
}

// A well-formed calibration for another image size.
std::string calibrationOfSize(cv::Size size) {
  const std::size_t n = static_cast<std::size_t>(size.area());
  algo::PixelPolynomial p;
  p.phase_inv_half = 1.0f;
  p.z[0] = 600.0f;
  algo::QuasiCalibrationInfo info;
  info.pose_count = 8;
  info.min_poses = 6;
  const algo::QuasiCalibration calib(size, std::vector<std::uint8_t>(n, 1),
                                     std::vector<algo::PixelPolynomial>(n, p), info);
  const auto bytes = calib.serialize();
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

class DaemonErrors : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    daemon_ = std::make_unique<QuickDaemon>();
    // One finished scan for the paths below a real id.
    const std::string id = startScan(daemon_->client(), {{"frames", 5}, {"save_bundle", false}});
    if (!id.empty() && finishScan(daemon_->client(), id).value("state", "") == "done") id_ = id;
  }
  static void TearDownTestSuite() {
    if (daemon_) daemon_->stop();
    daemon_.reset();
  }
  void SetUp() override {
    ASSERT_TRUE(daemon_) << "no daemon";
    ASSERT_FALSE(id_.empty()) << "the setup scan failed" << daemon_->stderrTail();
  }
  void TearDown() override {
    // Every test leaves the daemon alive.
    EXPECT_TRUE(daemon_->process().running()) << daemon_->stderrTail();
  }
  static const HttpClient& client() { return daemon_->client(); }

  static std::unique_ptr<QuickDaemon> daemon_;
  static std::string id_;
};
std::unique_ptr<QuickDaemon> DaemonErrors::daemon_;
std::string DaemonErrors::id_;

TEST_F(DaemonErrors, UnknownIdIs404) {
  const std::string unknown = "20991231-235959-dead";
  expectError(client().get("/api/v1/scans/" + unknown), {404}, "GET unknown scan");
  expectError(client().get("/api/v1/scans/" + unknown + "/cloud.ply"), {404}, "unknown's cloud");
  expectError(client().del("/api/v1/scans/" + unknown), {404}, "DELETE unknown scan");
  // A real scan's file that the API does not serve.
  expectError(client().get("/api/v1/scans/" + id_ + "/secret.txt"), {404}, "unknown file");
  expectError(client().get("/api/v1/nothing"), {404}, "unknown path");
  expectError(client().get("/api/v1/scans/"), {400, 404}, "trailing slash");
  expectError(client().get("/api/v1//scans"), {400, 404}, "double slash");
  EXPECT_EQ(client().get("/api/v1/scans/" + id_).status, 200) << "the real one is there";
}

TEST_F(DaemonErrors, InvalidIdsNeverReachTheFileSystem) {
  const std::vector<std::string> ids = {
      "..",  "%2e%2e",  "%2E%2E", "ABC",   "20261201-160102-3F9A", std::string(65, 'a'),
      "-rf", ".hidden", "a%2fb",  "a%00b", "..%2f..%2fetc",        "%2e%2e%2f%2e%2e"};
  for (const auto& id : ids) {
    for (const std::string& path : {"/api/v1/scans/" + id, "/api/v1/scans/" + id + "/cloud.ply"}) {
      const auto r = client().get(path);
      expectError(r, {400, 404}, "GET " + path);
      EXPECT_EQ(r.body.find("root:"), std::string::npos) << path;
    }
    expectError(client().del("/api/v1/scans/" + id), {400, 404}, "DELETE " + id);
  }
  // A file name that walks out of the scan.
  for (const std::string& path :
       {"/api/v1/scans/" + id_ + "/../" + id_ + "/cloud.ply",
        "/api/v1/scans/" + id_ + "/..%2f..%2fcalibration", "/api/v1/scans/" + id_ + "/scan.json/..",
        "/api/v1/scans/" + id_ + "/%2e%2e/" + id_ + "/cloud.ply"}) {
    const auto r = client().get(path);
    expectError(r, {400, 404}, "GET " + path);
  }
  // The static files stay inside the web root.
  for (const char* path : {"/../../../../etc/passwd", "/assets/../../../../etc/passwd",
                           "/assets/%2e%2e/%2e%2e/%2e%2e/etc/passwd", "/%2e%2e/etc/passwd"}) {
    const auto r = client().get(path);
    EXPECT_TRUE(r.status == 400 || r.status == 404) << path << ": " << r.describe();
    EXPECT_EQ(r.body.find("root:"), std::string::npos) << path;
  }
  // The 64-character limit is a limit, not an off-by-one: 64 is merely unknown.
  expectError(client().get("/api/v1/scans/" + std::string(64, 'a')), {404}, "64 characters");
  // And the scan is still there.
  EXPECT_EQ(client().get("/api/v1/scans").json().size(), 1u);
}

TEST_F(DaemonErrors, BadJsonAndBadOptionsAre400NamingThem) {
  const HttpClient::Headers json_type = {"Content-Type: application/json"};
  expectError(client().post("/api/v1/scans", "{\"mode\": ", json_type), {400}, "bad JSON", "json");
  expectError(client().post("/api/v1/scans", "[1, 2]", json_type), {400}, "not an object");
  expectError(client().postJson("/api/v1/scans", {{"bogus", 1}}), {400}, "unknown option", "bogus");
  expectError(client().postJson("/api/v1/scans", {{"frames", 2}}), {400}, "frames 2", "frames");
  expectError(client().postJson("/api/v1/scans", {{"frames", 1001}}), {400}, "frames 1001",
              "frames");
  expectError(client().postJson("/api/v1/scans", {{"frames", "many"}}), {400}, "frames string",
              "frames");
  expectError(client().postJson("/api/v1/scans", {{"mode", "sideways"}}), {400}, "mode", "mode");
  expectError(client().postJson("/api/v1/scans", {{"phase", "low"}}), {400}, "phase", "phase");
  expectError(client().postJson("/api/v1/scans", {{"save_bundle", "yes"}}), {400}, "save_bundle",
              "save_bundle");
  expectError(client().postJson("/api/v1/scans", {{"scene", "../../etc/passwd"}}), {400},
              "scene path", "scene");
  expectError(client().postJson("/api/v1/scans", {{"scene", "no_such_scene.toml"}}), {400},
              "unknown scene", "scene");
  // None of them started a scan.
  EXPECT_EQ(client().get("/api/v1/scans").json().size(), 1u);
  EXPECT_EQ(client().get("/api/v1/status").json().value("state", ""), "idle");
}

TEST_F(DaemonErrors, BadCalibrationLeavesTheInstalledOneUnchanged) {
  const auto before = client().get("/api/v1/calibration/main");
  ASSERT_EQ(before.status, 200) << before.describe();
  ASSERT_EQ(before.body, quickCalibration()) << "the installed calibration is the fixture's";
  const json info_before = client().get("/api/v1/calibration").json();

  const std::string& good = quickCalibration();
  std::string flipped = good;
  flipped[flipped.size() / 2] = static_cast<char>(flipped[flipped.size() / 2] ^ 0x5a);
  std::string bad_magic = good;
  bad_magic[0] = 'X';
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"garbage", "this is not a calibration file"},
      {"empty", ""},
      {"truncated", good.substr(0, good.size() / 2)},
      {"header only", good.substr(0, 64)},
      {"flipped byte (CRC)", flipped},
      {"bad magic", bad_magic},
      {"trailing bytes", good + "extra"}};
  for (const auto& [what, bytes] : bad)
    expectError(client().put("/api/v1/calibration", bytes), {400}, "calibration: " + what);
  expectError(client().put("/api/v1/calibration", calibrationOfSize({160, 128})), {422},
              "a 160×128 calibration on a 320×256 head");
  expectError(client().put("/api/v1/calibration?camera=nope", good), {400, 404}, "unknown camera");

  const auto after = client().get("/api/v1/calibration/main");
  ASSERT_EQ(after.status, 200) << after.describe();
  EXPECT_TRUE(after.body == before.body) << "the installed calibration changed";
  EXPECT_EQ(client().get("/api/v1/calibration").json(), info_before);

  // The good one installs again (200 with its info), byte for byte.
  const auto again = client().put("/api/v1/calibration", good);
  EXPECT_EQ(again.status, 200) << again.describe();
  // The camera's info (as GET /api/v1/calibration gives it under "main").
  const json answer = again.json();
  const json info = answer.contains("main") ? answer : json{{"main", answer}};
  EXPECT_EQ(info.at("main").value("installed", false), true) << info.dump();
  EXPECT_EQ(info.at("main").value("width", 0), 320) << info.dump();
  EXPECT_EQ(info.at("main").value("height", 0), 256) << info.dump();
  EXPECT_EQ(info.at("main").value("bytes", std::size_t{0}), good.size()) << info.dump();
  EXPECT_TRUE(client().get("/api/v1/calibration/main").body == good);
}

// One upload at a time (409) means concurrent ones: a client that waits for
// each answer before the next upload is never refused.
TEST_F(DaemonErrors, SequentialCalibrationUploadsAreNeverRefusedAsBusy) {
  int busy = 0;
  for (int i = 0; i < 8; ++i) {
    const bool good = i % 2 == 0;
    const auto r = client().put("/api/v1/calibration",
                                good ? quickCalibration() : std::string("not a calibration"));
    EXPECT_EQ(r.status, good ? 200 : 400) << "upload " << i << ": " << r.describe();
    if (r.status == 409) ++busy;
  }
  EXPECT_EQ(busy, 0) << "sequential uploads answered 409 (busy)";
  EXPECT_TRUE(client().get("/api/v1/calibration/main").body == quickCalibration());
}

TEST_F(DaemonErrors, LimitsAndMethods) {
  // A JSON body over 64 KiB: 413, no scan.
  const std::string huge =
      "{\"mode\": \"stop\", \"pad\": \"" + std::string(100 * 1024, 'x') + "\"}";
  expectError(client().post("/api/v1/scans", huge, {"Content-Type: application/json"}), {413},
              "100 KiB JSON");
  // Headers over 8 KiB: 431.
  const auto big_header =
      client().get("/api/v1/status", {"X-Padding: " + std::string(9 * 1024, 'h')});
  EXPECT_EQ(big_header.status, 431) << big_header.describe();
  // Wrong methods on known paths: 405 with Allow.
  const std::vector<std::pair<std::string, std::string>> wrong = {{"PUT", "/api/v1/status"},
                                                                  {"DELETE", "/api/v1/scans"},
                                                                  {"PUT", "/api/v1/scans/" + id_},
                                                                  {"POST", "/api/v1/scans/" + id_},
                                                                  {"POST", "/api/v1/calibration"},
                                                                  {"DELETE", "/api/v1/calibration"},
                                                                  {"POST", "/metrics"},
                                                                  {"PATCH", "/api/v1/scans"}};
  for (const auto& [method, path] : wrong) {
    const auto r = client().request(method, path, method == "PATCH" ? "{}" : "");
    expectError(r, {405}, method + " " + path);
    EXPECT_FALSE(r.header("allow").empty()) << method << " " << path << ": no Allow header";
  }
  // GET never changes state: the scan and the calibration are still there.
  EXPECT_EQ(client().get("/api/v1/scans").json().size(), 1u);
  EXPECT_EQ(client().get("/api/v1/calibration/main").status, 200);
}

TEST(DaemonLimits, CalibrationOverTheConfiguredLimitIs413) {
  TempDir config_dir;
  const fs::path config =
      config_dir.write("cylscan.toml", "[daemon]\nmax_calibration_bytes = 65536\n");
  QuickDaemon daemon(DaemonSetup({"--config", config.string()}, /*calibrate=*/false));
  const auto r = daemon.client().put("/api/v1/calibration", quickCalibration().substr(0, 200000));
  expectError(r, {413}, "200 kB calibration over a 64 KiB limit");
  EXPECT_EQ(daemon.client().get("/api/v1/calibration/main").status, 404);
  daemon.stop();
}

// The data directory on a 1 MiB file system (a tmpfs in a mount namespace of
// the daemon's own): one scan's outputs (~36 bytes a pixel, 2.9 MB at
// 320×256) do not fit, so the scan is refused before it starts.
TEST(DaemonLimits, NoRoomOnTheDiskIs507) {
  if (!canMountTmpfs()) GTEST_SKIP() << "no permission to mount a tmpfs in a mount namespace";
  DaemonSetup setup({}, /*calibrate=*/false);
  // Mount over the daemon's data directory, then run cylscand there.
  setup.wrapper = dataOnTmpfs("1m");
  QuickDaemon daemon(std::move(setup));
  const HttpClient& client = daemon.client();
  const json status = client.get("/api/v1/status").json();
  EXPECT_LT(status.value("disk_free_bytes", std::uint64_t{1} << 40), 2u * 1024 * 1024)
      << status.dump();
  const auto r = client.postJson("/api/v1/scans", {{"save_bundle", false}});
  expectError(r, {507}, "a scan on a 1 MiB disk");
  EXPECT_EQ(client.get("/api/v1/scans").json().size(), 0u);
  EXPECT_EQ(client.get("/api/v1/status").json().value("state", ""), "idle");
  daemon.stop();
}

}  // namespace
}  // namespace cylscan::test
