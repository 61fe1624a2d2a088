// SPDX-License-Identifier: Apache-2.0
// The cameras through cylscand on the quick head: the list, a PATCH kept
// across a restart, snapshot.jpg a JPEG of the camera's size that follows
// the exposure, and stream.mjpg giving pictures until a scan starts.
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

cv::Mat decoded(const std::string& jpeg) {
  const std::vector<unsigned char> bytes(jpeg.begin(), jpeg.end());
  return cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
}

json cameraNamed(const json& cameras, const std::string& name) {
  for (const json& c : cameras)
    if (c.at("name") == name) return c;
  return nullptr;
}

TEST(DaemonCameras, SnapshotFollowsThePatchedExposureAndIsKept) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  auto r = daemon.client().request("GET", "/api/v1/cameras");
  ASSERT_EQ(r.status, 200) << r.describe();
  const json main = cameraNamed(json::parse(r.body), "main");
  ASSERT_TRUE(main.is_object()) << r.body;
  const double exposure = main["controls"]["exposure_us"]["value"].get<double>();

  r = daemon.client().request("GET", "/api/v1/cameras/main/snapshot.jpg");
  ASSERT_EQ(r.status, 200) << r.describe() << daemon.stderrTail();
  const cv::Mat before = decoded(r.body);
  ASSERT_FALSE(before.empty());
  EXPECT_EQ(before.cols, main["width"].get<int>());
  EXPECT_EQ(before.rows, main["height"].get<int>());

  // A quarter of the exposure: the quick head's wall is far from full
  // scale, so the mean falls to about a quarter; half leaves room for the
  // offset, the noise and JPEG.
  r = daemon.client().request("PATCH", "/api/v1/cameras/main",
                              json{{"exposure_us", exposure / 4}}.dump(),
                              {"Content-Type: application/json"});
  ASSERT_EQ(r.status, 200) << r.describe();
  r = daemon.client().request("GET", "/api/v1/cameras/main/snapshot.jpg");
  ASSERT_EQ(r.status, 200) << r.describe();
  EXPECT_LT(cv::mean(decoded(r.body))[0], 0.5 * cv::mean(before)[0]);

  r = daemon.client().request("PATCH", "/api/v1/cameras/main", R"({"gain": 1e9})",
                              {"Content-Type: application/json"});
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(r.body.find("gain"), std::string::npos) << r.body;

  daemon.stop();
  daemon.start();
  r = daemon.client().request("GET", "/api/v1/cameras");
  ASSERT_EQ(r.status, 200);
  EXPECT_DOUBLE_EQ(
      cameraNamed(json::parse(r.body), "main")["controls"]["exposure_us"]["value"].get<double>(),
      exposure / 4);
}

TEST(DaemonCameras, StreamGivesPicturesUntilAScanStarts) {
  QuickDaemon daemon;
  std::string received;
  std::string id;
  const auto parts = [&] {
    std::size_t n = 0;
    for (auto p = received.find("--cylscanframe\r\n"); p != std::string::npos;
         p = received.find("--cylscanframe\r\n", p + 1))
      ++n;
    return n;
  };
  const auto r = daemon.client().stream(
      "/api/v1/cameras/main/stream.mjpg?overlay=saturation",
      [&](const std::string& chunk) {
        received += chunk;
        // Three pictures, then a scan: the stream must end by itself.
        if (id.empty() && parts() >= 3) id = startScan(daemon.client());
        return received.find("--cylscanframe--\r\n") == std::string::npos;
      },
      std::chrono::seconds(60));
  EXPECT_GE(parts(), 3u) << r.describe();
  EXPECT_FALSE(id.empty());
  EXPECT_NE(received.find("--cylscanframe--\r\n"), std::string::npos) << r.describe();
  EXPECT_NE(received.find("X-Cylscan-Focus: "), std::string::npos);
  // While the scan runs, no new live view.
  const auto during = daemon.client().request("GET", "/api/v1/cameras/main/snapshot.jpg");
  if (during.status != 200) {
    EXPECT_EQ(during.status, 409) << during.describe();
  }
  EXPECT_EQ(finishScan(daemon.client(), id)["state"], "done");
}

}  // namespace
}  // namespace cylscan::test
