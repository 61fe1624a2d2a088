// SPDX-License-Identifier: Apache-2.0
// The calibration session through cylscand on the quick head: every refusal
// (no session, bad bodies, a solve with too few views, an install before a
// solve, a rollback with nothing kept, captures while the head is busy),
// then the whole flow on an uncalibrated head, with the target poses the
// board ships (scenes/calibration/): checkerboard pairs, plane poses, the
// solve, the install, a check of the sphere that passes, and the rollback.
#include <algorithm>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

// The quick board's calibration scenes whose file name starts with `prefix`,
// as the API names them (calibration/<file>), in order.
std::vector<std::string> calibrationScenes(const std::string& prefix) {
  std::vector<std::string> out;
  const fs::path dir = quickFixture() / "board" / "scenes" / "calibration";
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.starts_with(prefix) && name.ends_with(".toml")) out.push_back("calibration/" + name);
  }
  std::sort(out.begin(), out.end());
  return out;
}

json session(const HttpClient& client) {
  const auto r = client.get("/api/v1/calibration/session");
  EXPECT_EQ(r.status, 200) << r.describe();
  return r.json();
}

// Polls the session until `done(session)` or the timeout.
template <typename Done>
json waitSession(const HttpClient& client, Done done,
                 std::chrono::seconds timeout = std::chrono::seconds(240)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  json s;
  while (std::chrono::steady_clock::now() < deadline) {
    s = session(client);
    if (!s.is_object() || done(s)) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ADD_FAILURE() << "the session did not get there in time: " << s.dump();
  return s;
}

bool planesSettled(const json& s) {
  return std::none_of(s["planes"].begin(), s["planes"].end(),
                      [](const json& p) { return p["state"] == "capturing"; });
}

TEST(DaemonCalibrationSession, RefusalsNameWhatIsWrong) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  HttpClient& c = daemon.client();
  EXPECT_EQ(c.get("/api/v1/calibration/session").status, 404);
  EXPECT_EQ(c.postJson("/api/v1/calibration/session/boards", json::object()).status, 404);
  EXPECT_EQ(c.postJson("/api/v1/calibration/session/solve", json::object()).status, 404);
  auto r = c.postJson("/api/v1/calibration/rollback", json::object());
  EXPECT_EQ(r.status, 404) << r.describe();
  EXPECT_NE(r.body.find("previous"), std::string::npos) << r.body;
  EXPECT_EQ(c.get("/api/v1/calibration/session/boards").status, 405);

  r = c.postJson("/api/v1/calibration/session", json{{"board", {{"cols", 1}}}});
  EXPECT_EQ(r.status, 400) << r.describe();
  EXPECT_NE(r.body.find("board.cols"), std::string::npos) << r.body;
  r = c.postJson("/api/v1/calibration/session", json::object());
  ASSERT_EQ(r.status, 201) << r.describe();
  EXPECT_EQ(r.json()["state"], "capturing");
  // The answer is the session as GET gives it, the virtual head's targets too.
  EXPECT_EQ(r.json(), session(c));
  EXPECT_EQ(r.json()["targets"]["boards"], json(calibrationScenes("board")));

  r = c.postJson("/api/v1/calibration/session/boards", json{{"scene", "no_such.toml"}});
  EXPECT_EQ(r.status, 400) << r.describe();
  EXPECT_NE(r.body.find("scene"), std::string::npos) << r.body;
  r = c.postJson("/api/v1/calibration/session/boards", json{{"scene", "../board.toml"}});
  EXPECT_EQ(r.status, 400) << r.describe();
  r = c.postJson("/api/v1/calibration/session/planes", json{{"exposure", 3}});
  EXPECT_EQ(r.status, 400) << r.describe();
  EXPECT_NE(r.body.find("exposure"), std::string::npos) << r.body;

  r = c.postJson("/api/v1/calibration/session/solve", json::object());
  EXPECT_EQ(r.status, 409) << r.describe();
  EXPECT_NE(r.body.find("checkerboard"), std::string::npos) << r.body;
  r = c.postJson("/api/v1/calibration/session/install", json::object());
  EXPECT_EQ(r.status, 409) << r.describe();
  EXPECT_NE(r.body.find("solve"), std::string::npos) << r.body;

  // A board the target is not in (the default scene): kept as tried, not found.
  r = c.postJson("/api/v1/calibration/session/boards", json::object());
  ASSERT_EQ(r.status, 201) << r.describe() << daemon.stderrTail();
  EXPECT_EQ(r.json()["index"], 0);
  EXPECT_FALSE(r.json()["found"]["main"].get<bool>() && r.json()["found"]["aux"].get<bool>());

  // While a plane pose is being taken the head is busy.
  const auto planes = calibrationScenes("plane");
  ASSERT_FALSE(planes.empty());
  r = c.postJson("/api/v1/calibration/session/planes", json{{"scene", planes[0]}});
  ASSERT_EQ(r.status, 202) << r.describe();
  EXPECT_EQ(r.json()["index"], 0);
  const auto during = c.postJson("/api/v1/calibration/session/boards", json::object());
  const auto patch = c.request("PATCH", "/api/v1/cameras/main", R"({"gain": 2})",
                               {"Content-Type: application/json"});
  const auto scan = c.postJson("/api/v1/scans", json::object());
  // The capture may already have ended on a fast machine: then each is taken.
  if (during.status != 201) {
    EXPECT_EQ(during.status, 409) << during.describe();
  }
  if (patch.status != 200) {
    EXPECT_EQ(patch.status, 409) << patch.describe();
  }
  if (scan.status != 202) {
    EXPECT_EQ(scan.status, 409) << scan.describe();
  } else {
    finishScan(c, scan.json()["id"]);
  }
  json s = waitSession(c, planesSettled);
  EXPECT_EQ(s["planes"][0]["state"], "done") << s.dump();
  ASSERT_TRUE(waitIdle(c));

  // Five pairs found: the guidance thread fits both cameras (4 are its least).
  const auto targets = calibrationScenes("board");
  for (std::size_t i = 0; i < 5; ++i) {
    r = c.postJson("/api/v1/calibration/session/boards", json{{"scene", targets[i * 7]}});
    ASSERT_EQ(r.status, 201) << r.describe();
    EXPECT_TRUE(r.json()["found"]["main"].get<bool>()) << r.body;
  }
  s = waitSession(c, [](const json& j) { return j["guidance"]["pairs"] == 5; });
  EXPECT_TRUE(s["guidance"]["cameras"]["main"]["sigma_px"]["cx"].is_number()) << s.dump();
  EXPECT_FALSE(s["guidance"]["enough"].get<bool>()) << "5 pairs are below the 10 asked";
  r = c.postJson("/api/v1/calibration/session/solve", json::object());
  EXPECT_EQ(r.status, 409) << "6 pairs are needed: " << r.describe();

  // A new session discards this one.
  r = c.postJson("/api/v1/calibration/session", json::object());
  ASSERT_EQ(r.status, 201) << r.describe();
  EXPECT_EQ(session(c)["planes"].size(), 0u);
}

// Every `step`-th of `all`, from the first.
std::vector<std::string> everyNth(const std::vector<std::string>& all, std::size_t step) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < all.size(); i += step)
    out.push_back(all[i]);
  return out;
}

TEST(DaemonCalibrationSession, TheHeadCalibratesItselfAndPassesTheCheck) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  HttpClient& c = daemon.client();
  // The board ships 96 boards (64 spread, then 32 tilted) and 14 planes. A
  // third of the boards, spread and tilted ones alike, and every other plane
  // keep this test to about a minute and still calibrate the quick head to
  // a few hundredths of a mm (the page's test, web.browser_calibration,
  // takes every target).
  const auto all_boards = calibrationScenes("board");
  const auto all_planes = calibrationScenes("plane");
  ASSERT_EQ(all_boards.size(), 96u);
  ASSERT_EQ(all_planes.size(), 14u);
  const auto boards = everyNth(all_boards, 3);
  const auto planes = everyNth(all_planes, 2);
  ASSERT_EQ(c.postJson("/api/v1/calibration/session", json::object()).status, 201);

  int found = 0;
  for (const std::string& scene : boards) {
    const auto r = c.postJson("/api/v1/calibration/session/boards", json{{"scene", scene}});
    ASSERT_EQ(r.status, 201) << scene << ": " << r.describe() << daemon.stderrTail();
    const json j = r.json();
    if (j["found"]["main"].get<bool>() && j["found"]["aux"].get<bool>()) ++found;
  }
  // Every shipped pose is in view of both cameras (simulate checks it).
  EXPECT_EQ(found, static_cast<int>(boards.size()));
  // The guidance follows the captures on a thread of its own.
  json s = waitSession(c, [&](const json& j) { return j["guidance"]["pairs"] == found; });
  EXPECT_EQ(s["boards"].size(), boards.size());
  ASSERT_TRUE(s["guidance"].is_object()) << s.dump();
  EXPECT_TRUE(s["guidance"]["cameras"]["main"]["sigma_px"]["cx"].is_number()) << s.dump();

  for (const std::string& scene : planes) {
    const auto r = c.postJson("/api/v1/calibration/session/planes", json{{"scene", scene}});
    ASSERT_EQ(r.status, 202) << scene << ": " << r.describe();
    ASSERT_TRUE(waitIdle(c));
  }
  s = waitSession(c, planesSettled);
  for (const json& p : s["planes"])
    EXPECT_EQ(p["state"], "done") << p.dump();

  auto r = c.postJson("/api/v1/calibration/session/solve", json::object());
  ASSERT_EQ(r.status, 202) << r.describe();
  s = waitSession(c, [](const json& j) { return j["state"] != "solving"; });
  ASSERT_EQ(s["state"], "solved") << s.dump() << daemon.stderrTail();
  EXPECT_DOUBLE_EQ(s["progress"].get<double>(), 1.0);
  const json& result = s["result"];
  // Rendered corners at 320×256: a tenth of a pixel or so.
  EXPECT_LT(result["stereo_rms_px"].get<double>(), 0.5) << result.dump();
  // A few pairs may be dropped as reprojection outliers, no more.
  EXPECT_GE(result["boards_used"].get<std::size_t>(), boards.size() - 4) << result.dump();
  // The quick fixture's own calibration reaches a few hundredths of a mm.
  EXPECT_LT(result["pooled_rmse_mm"].get<double>(), 0.2) << result.dump();
  for (const json& p : s["planes"])
    EXPECT_TRUE(p["valid_fraction"].is_number()) << p.dump();

  r = c.postJson("/api/v1/calibration/rollback", json::object());
  EXPECT_EQ(r.status, 404) << "nothing installed before: " << r.describe();
  r = c.postJson("/api/v1/calibration/session/install", json::object());
  ASSERT_EQ(r.status, 200) << r.describe();
  EXPECT_TRUE(r.json()["installed"].get<bool>());
  EXPECT_TRUE(c.get("/api/v1/status").json()["calibration"]["main"].get<bool>());

  r = c.postJson("/api/v1/checks", json{{"artifact", "sphere"}, {"radius_mm", 50}});
  ASSERT_EQ(r.status, 202) << r.describe();
  const std::string id = r.json()["id"];
  json check = json::object();
  for (int i = 0;
       i < 2400 && check.value("state", "") != "done" && check.value("state", "") != "failed";
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    for (const json& k : c.get("/api/v1/checks").json())
      if (k["id"] == id) check = k;
  }
  ASSERT_EQ(check.value("state", ""), "done") << check.dump();
  // The head's own calibration: the 50 mm sphere within the default 0.1 mm.
  EXPECT_TRUE(check["pass"].get<bool>()) << check.dump();
  EXPECT_NEAR(check["measured_radius_mm"].get<double>(), 50.0, 0.1) << check.dump();
  ASSERT_TRUE(waitIdle(c));

  // A second install keeps the first; the rollback swaps them back and forth.
  const auto bytes = c.get("/api/v1/calibration/main");
  ASSERT_EQ(bytes.status, 200);
  ASSERT_EQ(c.put("/api/v1/calibration", quickCalibration()).status, 200);
  r = c.postJson("/api/v1/calibration/rollback", json::object());
  ASSERT_EQ(r.status, 200) << r.describe();
  EXPECT_EQ(c.get("/api/v1/calibration/main").body, bytes.body);
  r = c.postJson("/api/v1/calibration/rollback", json::object());
  ASSERT_EQ(r.status, 200) << r.describe();
  EXPECT_EQ(c.get("/api/v1/calibration/main").body, quickCalibration());

  // The session survives a restart, solved.
  daemon.stop();
  daemon.start();
  s = session(daemon.client());
  EXPECT_EQ(s["state"], "solved") << s.dump();
  EXPECT_EQ(s["boards"].size(), boards.size());
}

}  // namespace
}  // namespace cylscan::test
