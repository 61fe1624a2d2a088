// SPDX-License-Identifier: Apache-2.0
// The fringe check through cylscand on the quick head: a short scan's
// figures for every camera, the advice following the exposure set through
// the API (the quick head's frames are rendered, not fitted to the rule),
// the pictures, and the refusals.
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

json fringeCheck(const HttpClient& client) {
  const auto r = client.postJson("/api/v1/fringe-check", json::object());
  EXPECT_EQ(r.status, 200) << r.describe();
  return r.status == 200 ? json::parse(r.body) : json();
}

json cameraOf(const json& check, const std::string& name) {
  for (const json& c : check.value("cameras", json::array()))
    if (c.at("name") == name) return c;
  return nullptr;
}

void setExposure(const HttpClient& client, double exposure_us) {
  const auto r =
      client.request("PATCH", "/api/v1/cameras/main", json{{"exposure_us", exposure_us}}.dump(),
                     {"Content-Type: application/json"});
  ASSERT_EQ(r.status, 200) << r.describe();
}

TEST(DaemonFringeCheck, TheAdviceFollowsTheExposure) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  const HttpClient& client = daemon.client();
  auto r = client.get("/api/v1/fringe-check/main.jpg");
  EXPECT_EQ(r.status, 404) << r.describe();

  // The quick head's profile exposure is the one its scans are validated
  // at: right for both cameras, most of the wall usable.
  const json right = fringeCheck(client);
  for (const char* name : {"main", "aux"}) {
    const json c = cameraOf(right, name);
    ASSERT_TRUE(c.is_object()) << right.dump();
    EXPECT_EQ(c["advice"], "right") << c.dump();
    EXPECT_GT(c["usable"].get<double>(), 0.5) << c.dump();
    EXPECT_EQ(c["saturated"].get<double>(), 0.0) << c.dump();
    EXPECT_GT(c["modulation_median"].get<double>(), 10.0) << c.dump();
  }
  r = client.get("/api/v1/fringe-check/main.jpg");
  ASSERT_EQ(r.status, 200) << r.describe();
  const std::vector<unsigned char> bytes(r.body.begin(), r.body.end());
  const cv::Mat picture = cv::imdecode(bytes, cv::IMREAD_COLOR);
  ASSERT_FALSE(picture.empty());
  r = client.get("/api/v1/cameras");
  ASSERT_EQ(r.status, 200);
  const json cameras = json::parse(r.body);
  EXPECT_EQ(picture.cols, cameras.at(0).at("width").get<int>());
  EXPECT_EQ(picture.rows, cameras.at(0).at("height").get<int>());
  const double exposure = cameras.at(0).at("controls").at("exposure_us").at("value").get<double>();

  // A fifth of the exposure: the crests fall to a fifth of their share of
  // full scale (0.95 at the profile's), below the 0.45 that asks for more.
  setExposure(client, exposure / 5);
  const json dark = fringeCheck(client);
  EXPECT_EQ(cameraOf(dark, "main")["advice"], "raise") << dark.dump();
  EXPECT_LT(cameraOf(dark, "main")["peak"].get<double>(),
            0.5 * cameraOf(right, "main")["peak"].get<double>());
  EXPECT_EQ(cameraOf(dark, "aux")["advice"], "right") << "aux kept its exposure";

  // Four times: the wall clips over most of the picture.
  setExposure(client, exposure * 4);
  const json bright = fringeCheck(client);
  const json main = cameraOf(bright, "main");
  EXPECT_EQ(main["advice"], "lower") << bright.dump();
  EXPECT_GT(main["saturated"].get<double>(), 0.1) << main.dump();
  EXPECT_LT(main["usable"].get<double>(), cameraOf(right, "main")["usable"].get<double>());
  r = client.get("/api/v1/fringe-check/main.jpg");
  ASSERT_EQ(r.status, 200) << r.describe();
  const std::vector<unsigned char> clipped(r.body.begin(), r.body.end());
  const cv::Mat red = cv::imdecode(clipped, cv::IMREAD_COLOR);
  ASSERT_FALSE(red.empty());
  // Saturated pixels are red: the mean's red channel leads the others.
  const cv::Scalar mean = cv::mean(red);
  EXPECT_GT(mean[2], mean[1] + 50) << mean;
}

TEST(DaemonFringeCheck, RefusalsNameWhatIsWrong) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  const HttpClient& client = daemon.client();
  auto r = client.postJson("/api/v1/fringe-check", json{{"frames", 3}});
  EXPECT_EQ(r.status, 400) << r.describe();
  EXPECT_NE(r.body.find("frames"), std::string::npos) << r.body;
  r = client.postJson("/api/v1/fringe-check", json{{"scene", "../board.toml"}});
  EXPECT_EQ(r.status, 400) << r.describe();
  EXPECT_NE(r.body.find("scene"), std::string::npos) << r.body;
  r = client.post("/api/v1/fringe-check", "[1]", {"Content-Type: application/json"});
  EXPECT_EQ(r.status, 400) << r.describe();
  r = client.get("/api/v1/fringe-check");
  EXPECT_EQ(r.status, 405) << r.describe();
  r = client.get("/api/v1/fringe-check/main.png");
  EXPECT_EQ(r.status, 404) << r.describe();

  // While a scan runs the head takes no fringe check.
  const std::string id = startScan(client);
  r = client.postJson("/api/v1/fringe-check", json::object());
  EXPECT_EQ(r.status, 409) << r.describe();
  EXPECT_NE(r.body.find("scan " + id), std::string::npos) << r.body;
  EXPECT_EQ(finishScan(client, id)["state"], "done");
  // And the scans are not mixed with the checks.
  fringeCheck(client);
  r = client.get("/api/v1/scans");
  ASSERT_EQ(r.status, 200);
  EXPECT_EQ(json::parse(r.body).size(), 1u) << r.body;
}

}  // namespace
}  // namespace cylscan::test
