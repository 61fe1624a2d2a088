// SPDX-License-Identifier: Apache-2.0
// Authentication of a cylscand started with --token: every request but
// GET /api/v1/status needs "Authorization: Bearer TOKEN"; a missing or wrong
// token, or one in the query string, is 401 with WWW-Authenticate: Bearer and
// changes nothing.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

const std::string kToken = "e2e-secret-7f3a9c1d";

struct Request {
  std::string method, path, body;
};

void expect401(const HttpResponse& r, const std::string& what) {
  EXPECT_EQ(r.status, 401) << what << ": " << r.describe();
  EXPECT_EQ(r.header("www-authenticate").rfind("Bearer", 0), 0u)
      << what << ": WWW-Authenticate is '" << r.header("www-authenticate") << "'";
  EXPECT_FALSE(r.error().empty()) << what << ": not a JSON error: " << r.body;
}

TEST(DaemonAuth, TokenRequiredWhenConfigured) {
  QuickDaemon daemon(DaemonSetup({"--token", kToken}, /*calibrate=*/true, kToken));
  const HttpClient& client = daemon.client();
  const HttpClient::Headers good = {"Authorization: Bearer " + kToken};

  // The status needs no token.
  const auto status = client.get("/api/v1/status");
  EXPECT_EQ(status.status, 200) << status.describe();
  EXPECT_EQ(status.json().at("calibration").at("main"), true) << status.body;

  // A scan made with the token, for the paths below a real id.
  const auto started =
      client.postJson("/api/v1/scans", {{"frames", 5}, {"save_bundle", false}}, good);
  ASSERT_EQ(started.status, 202) << started.describe() << daemon.stderrTail();
  const std::string id = started.json().at("id");
  HttpClient authed(client.baseUrl());
  authed.setDefaultHeaders(good);
  ASSERT_EQ(finishScan(authed, id).value("state", ""), "done");

  const std::string& calib = quickCalibration();
  const std::vector<Request> requests = {
      {"POST", "/api/v1/scans", "{}"},
      {"DELETE", "/api/v1/scans/" + id, ""},
      {"PUT", "/api/v1/calibration", calib.substr(0, 100)},
      {"GET", "/api/v1/scans", ""},
      {"GET", "/api/v1/scans/" + id, ""},
      {"GET", "/api/v1/scans/" + id + "/cloud.ply", ""},
      {"GET", "/api/v1/calibration", ""},
      {"GET", "/api/v1/calibration/main", ""},
      {"GET", "/metrics", ""},
  };
  const std::vector<std::pair<std::string, HttpClient::Headers>> wrong = {
      {"no token", {}},
      {"wrong token", {"Authorization: Bearer wrong-" + kToken}},
      {"token prefix", {"Authorization: Bearer " + kToken.substr(0, kToken.size() - 1)}},
      {"token plus a byte", {"Authorization: Bearer " + kToken + "x"}},
      {"empty bearer", {"Authorization: Bearer "}},
      {"basic scheme", {"Authorization: Basic " + kToken}},
      {"bare token", {"Authorization: " + kToken}},
  };
  for (const auto& r : requests) {
    for (const auto& [what, headers] : wrong) {
      expect401(client.request(r.method, r.path, r.body, headers),
                r.method + " " + r.path + " with " + what);
    }
    // The token in the query string is never accepted.
    for (const char* name : {"token", "access_token"}) {
      const std::string sep = r.path.find('?') == std::string::npos ? "?" : "&";
      expect401(client.request(r.method, r.path + sep + name + "=" + kToken, r.body),
                r.method + " " + r.path + " with ?" + name + "=");
    }
  }
  // The events stream too (a short timeout: a 200 would be a stream).
  expect401(client.request("GET", "/api/v1/events", {}, {}, std::chrono::seconds(5)),
            "GET /api/v1/events without token");

  // Nothing changed: still one scan, still the same calibration, idle.
  const auto list = authed.get("/api/v1/scans");
  ASSERT_EQ(list.status, 200) << list.describe();
  EXPECT_EQ(list.json().size(), 1u) << list.body;
  EXPECT_TRUE(authed.get("/api/v1/calibration/main").body == calib);
  EXPECT_EQ(client.get("/api/v1/status").json().value("state", ""), "idle");

  // The right token works for every one of them.
  EXPECT_EQ(authed.get("/api/v1/scans/" + id).status, 200);
  EXPECT_EQ(authed.get("/api/v1/scans/" + id + "/cloud.ply").status, 200);
  EXPECT_EQ(authed.get("/api/v1/calibration").status, 200);
  EXPECT_EQ(authed.get("/metrics").status, 200);
  EXPECT_EQ(authed.put("/api/v1/calibration", calib).status, 200);
  EXPECT_EQ(authed.del("/api/v1/scans/" + id).status, 204);
  EXPECT_EQ(authed.get("/api/v1/scans/" + id).status, 404);
  const auto again = authed.postJson("/api/v1/scans", {{"frames", 5}, {"save_bundle", false}});
  ASSERT_EQ(again.status, 202) << again.describe();
  EXPECT_EQ(finishScan(authed, again.json().at("id")).value("state", ""), "done");
  daemon.stop();
}

// allow_loopback_without_token: the tests' client is on 127.0.0.1, so it
// needs no token for any request.
TEST(DaemonAuth, LoopbackWithoutTokenWhenTheConfigSaysSo) {
  TempDir config_dir;
  const fs::path config =
      config_dir.write("cylscan.toml", "[daemon]\ntoken = \"" + kToken +
                                           "\"\nallow_loopback_without_token = true\n");
  QuickDaemon daemon(DaemonSetup({"--config", config.string()}, /*calibrate=*/false));
  const HttpClient& client = daemon.client();
  EXPECT_EQ(client.put("/api/v1/calibration", quickCalibration()).status, 200);
  EXPECT_EQ(client.get("/api/v1/scans").status, 200);
  const std::string id = startScan(client, {{"frames", 5}, {"save_bundle", false}});
  ASSERT_FALSE(id.empty()) << daemon.stderrTail();
  EXPECT_EQ(finishScan(client, id).value("state", ""), "done");
  EXPECT_EQ(client.del("/api/v1/scans/" + id).status, 204);
  daemon.stop();
}

TEST(DaemonAuth, NoTokenConfiguredNeedsNone) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  EXPECT_EQ(daemon.client().get("/api/v1/scans").status, 200);
  EXPECT_EQ(daemon.client().get("/api/v1/calibration").status, 200);
  daemon.stop();
}

}  // namespace
}  // namespace cylscan::test
