// SPDX-License-Identifier: Apache-2.0
// Checks against a known artifact through cylscand on the quick head: the
// refusals (no calibration, bad bodies), a check of the quick head's sphere
// that passes, one with a tolerance no head meets that fails, and the
// history kept newest first across a restart.
#include <chrono>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

// The quick head's default scene (sphere_on_plane) holds a sphere of this
// radius (board/sim/scenes/sphere_on_plane.toml).
constexpr double kSphereRadiusMm = 50.0;

// Polls GET /api/v1/checks until the check `id` is done or failed.
json waitForCheck(const HttpClient& client, const std::string& id,
                  std::chrono::seconds timeout = std::chrono::seconds(120)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  json last;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto r = client.get("/api/v1/checks");
    if (r.status != 200) {
      ADD_FAILURE() << r.describe();
      return json::object();
    }
    for (const json& c : r.json()) {
      if (c.value("id", "") != id) continue;
      last = c;
      const std::string state = c.value("state", "");
      if (state == "done" || state == "failed") return c;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ADD_FAILURE() << "check " << id << " not finished: " << last.dump();
  return last;
}

std::string startCheck(const HttpClient& client, const json& body) {
  const auto r = client.postJson("/api/v1/checks", body);
  EXPECT_EQ(r.status, 202) << r.describe();
  const json j = r.json();
  if (r.status != 202 || !j.is_object() || !j.contains("id")) return {};
  // A check is a scan of the artifact: Location names that scan.
  EXPECT_EQ(r.header("location"), "/api/v1/scans/" + j["id"].get<std::string>());
  return j["id"];
}

TEST(DaemonChecks, RefusedWithoutCalibration) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  const auto r =
      daemon.client().postJson("/api/v1/checks", json{{"artifact", "sphere"}, {"radius_mm", 50}});
  EXPECT_EQ(r.status, 409) << r.describe();
  EXPECT_NE(r.body.find("calibrat"), std::string::npos) << r.body;
  const auto list = daemon.client().get("/api/v1/checks");
  ASSERT_EQ(list.status, 200);
  EXPECT_EQ(list.json(), json::array());
}

TEST(DaemonChecks, BadBodiesNameWhatIsWrong) {
  QuickDaemon daemon;
  const struct {
    json body;
    const char* names;
  } cases[] = {
      {json{{"radius_mm", 50}}, "artifact"},
      {json{{"artifact", "cube"}, {"radius_mm", 50}}, "artifact"},
      {json{{"artifact", "sphere"}}, "radius_mm"},
      {json{{"artifact", "sphere"}, {"radius_mm", -1}}, "radius_mm"},
      {json{{"artifact", "sphere"}, {"radius_mm", "50"}}, "radius_mm"},
      {json{{"artifact", "sphere"}, {"radius_mm", 50}, {"tolerance_mm", 0}}, "tolerance_mm"},
      {json{{"artifact", "sphere"}, {"radius_mm", 50}, {"speed", 2}}, "speed"},
      {json{{"artifact", "sphere"}, {"radius_mm", 50}, {"scene", "../../etc/passwd"}}, "scene"},
      {json::array(), "object"},
  };
  for (const auto& c : cases) {
    const auto r = daemon.client().postJson("/api/v1/checks", c.body);
    EXPECT_EQ(r.status, 400) << c.body.dump() << ": " << r.describe();
    EXPECT_NE(r.body.find(c.names), std::string::npos) << c.body.dump() << ": " << r.body;
  }
  EXPECT_EQ(daemon.client().get("/api/v1/checks").json(), json::array());
}

TEST(DaemonChecks, TheQuickHeadPassesAndTheHistoryIsKept) {
  QuickDaemon daemon;
  const std::string first =
      startCheck(daemon.client(), json{{"artifact", "sphere"}, {"radius_mm", kSphereRadiusMm}});
  ASSERT_FALSE(first.empty());
  // A second request while the first runs is refused like a second scan.
  const auto busy = daemon.client().postJson(
      "/api/v1/checks", json{{"artifact", "sphere"}, {"radius_mm", kSphereRadiusMm}});
  if (busy.status != 202) {
    EXPECT_EQ(busy.status, 409) << busy.describe();
  } else {
    waitForCheck(daemon.client(), busy.json()["id"]);
  }
  const json done = waitForCheck(daemon.client(), first);
  ASSERT_EQ(done.value("state", ""), "done") << done.dump() << daemon.stderrTail();
  // The quick head's calibration (fixture, 64 boards, 320×256) measures the
  // sphere to a few hundredths of a mm; the default tolerance is 0.1 mm.
  EXPECT_NEAR(done["measured_radius_mm"].get<double>(), kSphereRadiusMm, 0.1) << done.dump();
  EXPECT_DOUBLE_EQ(done["tolerance_mm"].get<double>(), 0.1);
  EXPECT_TRUE(done["pass"].get<bool>()) << done.dump();
  // At 320×256 the sphere's cap is thousands of points; RMSE is the noise
  // of the fit, below the RANSAC inlier threshold of 0.5 mm.
  EXPECT_GT(done["points"].get<int>(), 1000) << done.dump();
  EXPECT_GT(done["rmse_mm"].get<double>(), 0.0);
  EXPECT_LT(done["rmse_mm"].get<double>(), 0.5);
  EXPECT_TRUE(done.contains("probing_error_form_mm")) << done.dump();
  EXPECT_TRUE(done.contains("probing_error_size_mm")) << done.dump();
  EXPECT_NEAR(done["probing_error_size_mm"].get<double>(),
              2 * (done["measured_radius_mm"].get<double>() - kSphereRadiusMm), 1e-9);
  EXPECT_FALSE(done.value("created", "").empty());
  ASSERT_TRUE(waitIdle(daemon.client()));

  // The same sphere against a tolerance far below the noise: a failed check
  // that is still a finished one.
  const std::string second = startCheck(
      daemon.client(),
      json{{"artifact", "sphere"}, {"radius_mm", kSphereRadiusMm}, {"tolerance_mm", 1e-6}});
  ASSERT_FALSE(second.empty());
  const json strict = waitForCheck(daemon.client(), second);
  ASSERT_EQ(strict.value("state", ""), "done") << strict.dump();
  EXPECT_FALSE(strict["pass"].get<bool>()) << strict.dump();
  ASSERT_TRUE(waitIdle(daemon.client()));

  daemon.stop();
  daemon.start();
  const auto r = daemon.client().get("/api/v1/checks");
  ASSERT_EQ(r.status, 200) << r.describe();
  const json history = r.json();
  ASSERT_GE(history.size(), 2u) << history.dump();
  EXPECT_EQ(history[0]["id"], second);  // newest first
  EXPECT_EQ(history[history.size() - 1]["id"], first);
  EXPECT_DOUBLE_EQ(history[history.size() - 1]["measured_radius_mm"].get<double>(),
                   done["measured_radius_mm"].get<double>());
}

}  // namespace
}  // namespace cylscan::test
