// SPDX-License-Identifier: Apache-2.0
// Scans through the HTTP API of a running cylscand on the quick head
// (320×256, calibrated by the fixture "quick_head"), checked against the
// virtual head's truth of the board's default scene, sphere_on_plane: a
// 50 mm sphere at z = 570 mm in front of a plane at z = 640 mm.
//
// Bounds, as in tests/cli/end_to_end_test.cpp for this resolution:
// - free-fit sphere radius within 0.3 mm of the true 50 mm: the quasi
//   method's sphere error at 320×256 (f ≈ 1113 px) is ~0.1 mm;
// - RMS distance of the points to the true sphere and to the true plane
//   below 1 mm: the absolute placement inherits the stereo calibration's
//   error (σ(fx) ≈ 0.2 % is ~1.2 mm of depth at 580 mm), which the
//   quasi-calibration copies;
// - points farther than 5 mm from both true surfaces below 2 %: the mixed
//   pixels along the sphere's outline, where its limb meets the backdrop
//   70 mm behind (≈ 2π·97 px ≈ 600 pixels of the ~70 000 valid ones, ~1 %).
#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "algo/surface_fit.hpp"
#include "formats/images.hpp"
#include "formats/point_cloud.hpp"
#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

constexpr int kWidth = 320, kHeight = 256;

Eigen::Vector3d vec(const json& v) {
  return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
}

json truthObject(const std::string& type) {
  const json truth = quickTruth();
  for (const auto& o : truth.at("scenes").at("sphere_on_plane").at("objects"))
    if (o.at("type") == type) return o;
  throw std::runtime_error("truth.json: no " + type + " in sphere_on_plane");
}

std::vector<std::string> files(const json& scan) {
  std::vector<std::string> names;
  if (scan.contains("files") && scan["files"].is_array())
    for (const auto& f : scan["files"])
      names.push_back(f.get<std::string>());
  return names;
}
bool has(const std::vector<std::string>& list, const std::string& name) {
  return std::find(list.begin(), list.end(), name) != list.end();
}

// Every file the API names: 200 exactly when the scan lists it, else 404.
void expectFilesAsListed(const HttpClient& client, const std::string& id, const json& scan) {
  const auto listed = files(scan);
  for (const char* name : {"cloud.ply", "depth.tiff", "texture.png", "phase.png", "depth.png"}) {
    const auto r = client.get("/api/v1/scans/" + id + "/" + name);
    EXPECT_EQ(r.status, has(listed, name) ? 200 : 404) << name << ": " << r.describe();
  }
}

cv::Mat decodePng(const HttpResponse& r, const std::string& what) {
  EXPECT_EQ(r.status, 200) << what << ": " << r.describe();
  EXPECT_EQ(r.header("content-type"), "image/png") << what;
  const std::vector<uchar> bytes(r.body.begin(), r.body.end());
  cv::Mat image = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
  EXPECT_FALSE(image.empty()) << what << " does not decode as an image";
  if (!image.empty()) {
    EXPECT_EQ(image.cols, kWidth) << what;
    EXPECT_EQ(image.rows, kHeight) << what;
  }
  return image;
}

struct CloudCheck {
  std::size_t points = 0, sphere = 0, plane = 0, outliers = 0;
  double sphere_rms = NAN, plane_rms = NAN, free_radius = NAN, centre_offset = NAN;
};

// The points against the true sphere and plane: each point belongs to the
// nearer true surface; farther than 5 mm from both, it is an outlier.
CloudCheck checkCloud(const formats::PointCloud& cloud) {
  const json sphere = truthObject("sphere");
  const json plane = truthObject("plane");
  const Eigen::Vector3d c = vec(sphere.at("center"));
  const double r = sphere.at("radius");
  const Eigen::Vector3d p0 = vec(plane.at("point"));
  const Eigen::Vector3d n = vec(plane.at("normal")).normalized();
  CloudCheck out;
  out.points = cloud.size();
  double s2 = 0, p2 = 0;
  algo::Points3d on_sphere;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d x(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
    const double ds = (x - c).norm() - r;
    const double dp = n.dot(x - p0);
    if (std::min(std::abs(ds), std::abs(dp)) > 5.0) {
      ++out.outliers;
    } else if (std::abs(ds) < std::abs(dp)) {
      ++out.sphere;
      s2 += ds * ds;
      on_sphere.push_back(x);
    } else {
      ++out.plane;
      p2 += dp * dp;
    }
  }
  if (out.sphere) out.sphere_rms = std::sqrt(s2 / static_cast<double>(out.sphere));
  if (out.plane) out.plane_rms = std::sqrt(p2 / static_cast<double>(out.plane));
  if (on_sphere.size() >= 4) {
    const algo::SphereFit fit = algo::fitSphere(on_sphere);
    out.free_radius = fit.sphere.radius;
    out.centre_offset = (fit.sphere.centre - c).norm();
  }
  return out;
}

TEST(DaemonScan, PostToDownloadedPlyMatchesTheTruth) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  const json status = client.get("/api/v1/status").json();
  ASSERT_TRUE(status.is_object()) << daemon.stderrTail();
  EXPECT_EQ(status.value("state", ""), "idle") << status.dump();
  EXPECT_EQ(status.at("calibration").at("main"), true) << status.dump();

  const std::string id = startScan(client);
  ASSERT_FALSE(id.empty()) << daemon.stderrTail();
  const json scan = waitForScan(client, id);
  ASSERT_EQ(scan.value("state", ""), "done") << scan.dump() << daemon.stderrTail();
  EXPECT_EQ(scan.value("id", ""), id);
  EXPECT_DOUBLE_EQ(scan.value("progress", -1.0), 1.0);
  EXPECT_EQ(scan.value("frames_done", -1), scan.value("frames", -2)) << scan.dump();
  EXPECT_EQ(scan.value("frames", 0), 50) << "the board's 2×25 frames: " << scan.dump();
  for (const char* name : {"cloud.ply", "depth.tiff", "texture.png", "phase.png", "depth.png"})
    EXPECT_TRUE(has(files(scan), name)) << name << " missing from " << scan.dump();
  {
    // At once: a scan that says "done" serves its files.
    SCOPED_TRACE("the files, right after the scan said done");
    expectFilesAsListed(client, id, scan);
  }
  ASSERT_TRUE(waitIdle(client));
  expectFilesAsListed(client, id, scan);

  // The cloud against the truth.
  const auto ply = client.get("/api/v1/scans/" + id + "/cloud.ply");
  ASSERT_EQ(ply.status, 200) << ply.describe();
  EXPECT_EQ(ply.header("content-type"), "application/octet-stream");
  const fs::path ply_file = daemon.dir().write("cloud.ply", ply.body);
  const formats::PointCloud cloud = formats::readPly(ply_file);
  EXPECT_EQ(scan.value("points", std::size_t{0}), cloud.size()) << scan.dump();
  const CloudCheck check = checkCloud(cloud);
  std::cout << "[daemon e2e] cloud: " << check.points << " points (sphere " << check.sphere
            << ", plane " << check.plane << ", outliers " << check.outliers << "), free radius "
            << check.free_radius << " mm, centre off by " << check.centre_offset
            << " mm, rms to the true sphere " << check.sphere_rms << " mm, to the true plane "
            << check.plane_rms << " mm; duration " << scan.value("duration_s", -1.0) << " s\n";
  EXPECT_GT(check.sphere, 5000u);
  EXPECT_GT(check.plane, 5000u);
  EXPECT_LT(static_cast<double>(check.outliers), 0.02 * static_cast<double>(check.points));
  EXPECT_NEAR(check.free_radius, 50.0, 0.3);
  EXPECT_LT(check.centre_offset, 1.5);
  EXPECT_LT(check.sphere_rms, 1.0);
  EXPECT_LT(check.plane_rms, 1.0);

  // The images decode at the head's size.
  const auto tiff = client.get("/api/v1/scans/" + id + "/depth.tiff");
  ASSERT_EQ(tiff.status, 200) << tiff.describe();
  EXPECT_EQ(tiff.header("content-type"), "image/tiff");
  const cv::Mat depth = formats::readFloatTiff(daemon.dir().write("depth.tiff", tiff.body));
  EXPECT_EQ(depth.type(), CV_32FC1);
  EXPECT_EQ(depth.cols, kWidth);
  EXPECT_EQ(depth.rows, kHeight);
  // The depth map's valid pixels are the cloud's points, at the scene's depths.
  int valid = 0;
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 0; u < depth.cols; ++u) {
      const float z = depth.at<float>(v, u);
      if (std::isfinite(z)) {
        ++valid;
        EXPECT_TRUE(z > 500 && z < 700) << "z " << z << " at " << u << "," << v;
        if (!(z > 500 && z < 700)) return;
      }
    }
  EXPECT_EQ(static_cast<std::size_t>(valid), cloud.size());
  const cv::Mat texture = decodePng(client.get("/api/v1/scans/" + id + "/texture.png"), "texture");
  const cv::Mat phase = decodePng(client.get("/api/v1/scans/" + id + "/phase.png"), "phase");
  const cv::Mat depth_png = decodePng(client.get("/api/v1/scans/" + id + "/depth.png"), "depth");
  if (!texture.empty()) {
    double lo = 0, hi = 0;
    cv::minMaxLoc(texture.reshape(1), &lo, &hi);
    EXPECT_LT(lo, hi) << "the texture is flat";
  }
  if (!phase.empty()) {
    EXPECT_EQ(phase.channels(), 3) << "a colour-mapped preview";
  }
  if (!depth_png.empty()) {
    EXPECT_EQ(depth_png.channels(), 3) << "a colour-mapped preview";
  }

  // A second scan: the list is newest first.
  const std::string second = startScan(client, {{"save_bundle", false}});
  ASSERT_FALSE(second.empty());
  EXPECT_NE(second, id);
  EXPECT_EQ(waitForScan(client, second).value("state", ""), "done");
  ASSERT_TRUE(waitIdle(client));
  const json list = client.get("/api/v1/scans").json();
  ASSERT_TRUE(list.is_array()) << list.dump();
  ASSERT_EQ(list.size(), 2u) << list.dump();
  EXPECT_EQ(list[0].value("id", ""), second);
  EXPECT_EQ(list[1].value("id", ""), id);
  EXPECT_GE(list[0].value("created", ""), list[1].value("created", ""));
  EXPECT_EQ(client.get("/api/v1/status").json().value("scans", -1), 2);

  // DELETE removes it: 204, then 404 for it and its files.
  const auto deleted = client.del("/api/v1/scans/" + id);
  EXPECT_EQ(deleted.status, 204) << deleted.describe();
  EXPECT_TRUE(deleted.body.empty());
  EXPECT_EQ(client.get("/api/v1/scans/" + id).status, 404);
  EXPECT_EQ(client.get("/api/v1/scans/" + id + "/cloud.ply").status, 404);
  EXPECT_EQ(client.del("/api/v1/scans/" + id).status, 404);
  const json after = client.get("/api/v1/scans").json();
  ASSERT_EQ(after.size(), 1u) << after.dump();
  EXPECT_EQ(after[0].value("id", ""), second);
  daemon.stop();
}

TEST(DaemonScan, SecondScanWhileOneRunsIs409) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  // 2×200 frames: several seconds of scanning, long enough for the requests below.
  const std::string id = startScan(client, {{"frames", 200}, {"save_bundle", false}});
  ASSERT_FALSE(id.empty()) << daemon.stderrTail();
  const auto second = client.postJson("/api/v1/scans", json::object());
  const json during = client.get("/api/v1/scans/" + id).json();
  const json status = client.get("/api/v1/status").json();
  const auto delete_running = client.del("/api/v1/scans/" + id);
  // Only meaningful if the first one was still running at the time.
  ASSERT_NE(during.value("state", ""), "done") << "the scan finished too soon: " << during.dump();
  EXPECT_EQ(second.status, 409) << second.describe();
  EXPECT_FALSE(second.error().empty()) << second.body;
  EXPECT_EQ(status.value("state", ""), "scanning") << status.dump();
  EXPECT_EQ(status.value("current_scan", json()), id) << status.dump();
  EXPECT_EQ(delete_running.status, 409) << delete_running.describe();

  const json scan = waitForScan(client, id);
  EXPECT_EQ(scan.value("state", ""), "done") << scan.dump() << daemon.stderrTail();
  EXPECT_EQ(scan.value("frames", 0), 400) << scan.dump();
  EXPECT_EQ(scan.at("options").value("frames", 0), 200) << scan.dump();
  ASSERT_TRUE(waitIdle(client));
  // Only one scan was made, and the next one is accepted.
  EXPECT_EQ(client.get("/api/v1/scans").json().size(), 1u);
  const std::string next = startScan(client, {{"frames", 5}, {"save_bundle", false}});
  ASSERT_FALSE(next.empty());
  EXPECT_EQ(waitForScan(client, next).value("state", ""), "done");
  daemon.stop();
}

TEST(DaemonScan, WithoutCalibrationHasTextureAndPhaseButNoCloud) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  const HttpClient& client = daemon.client();
  const json status = client.get("/api/v1/status").json();
  EXPECT_EQ(status.at("calibration").at("main"), false) << status.dump();
  EXPECT_EQ(client.get("/api/v1/calibration/main").status, 404);
  EXPECT_EQ(client.get("/api/v1/calibration").json().at("main").value("installed", true), false);

  const std::string id = startScan(client, {{"save_bundle", false}});
  ASSERT_FALSE(id.empty()) << daemon.stderrTail();
  const json scan = waitForScan(client, id);
  ASSERT_EQ(scan.value("state", ""), "done") << scan.dump() << daemon.stderrTail();
  const auto listed = files(scan);
  EXPECT_FALSE(has(listed, "cloud.ply")) << scan.dump();
  EXPECT_TRUE(has(listed, "texture.png")) << scan.dump();
  EXPECT_TRUE(has(listed, "phase.png")) << scan.dump();
  EXPECT_EQ(scan.value("points", std::size_t{0}), 0u) << scan.dump();
  if (scan.contains("calibrated")) {
    EXPECT_EQ(scan["calibrated"], false) << scan.dump();
  }
  ASSERT_TRUE(waitIdle(client));
  EXPECT_EQ(client.get("/api/v1/scans/" + id + "/cloud.ply").status, 404);
  decodePng(client.get("/api/v1/scans/" + id + "/texture.png"), "texture");
  decodePng(client.get("/api/v1/scans/" + id + "/phase.png"), "phase");
  expectFilesAsListed(client, id, scan);
  daemon.stop();
}

TEST(DaemonScan, RequestsAreAnsweredWhileAScanRuns) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  const std::string id = startScan(client, {{"frames", 200}, {"save_bundle", false}});
  ASSERT_FALSE(id.empty()) << daemon.stderrTail();
  // Four clients at once, each asking 25 times: every answer is a 200.
  std::vector<std::thread> threads;
  std::vector<int> ok(4, 0);
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      const std::string paths[] = {"/api/v1/status", "/api/v1/scans", "/api/v1/scans/" + id,
                                   "/metrics"};
      for (int i = 0; i < 25; ++i)
        if (client.get(paths[(t + i) % 4]).status == 200) ++ok[t];
    });
  }
  for (auto& th : threads)
    th.join();
  const json during = client.get("/api/v1/scans/" + id).json();
  for (int t = 0; t < 4; ++t)
    EXPECT_EQ(ok[t], 25) << "client " << t;
  EXPECT_EQ(finishScan(client, id).value("state", ""), "done")
      << "the scan was " << during.value("state", "") << " at the end of the requests";
  daemon.stop();
}

TEST(DaemonScan, RetentionRemovesTheOldest) {
  TempDir config_dir;
  const fs::path config = config_dir.write("cylscan.toml", "[retention]\nmax_scans = 2\n");
  QuickDaemon daemon(DaemonSetup({"--config", config.string()}));
  const HttpClient& client = daemon.client();
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    ids.push_back(startScan(client, {{"frames", 5}, {"save_bundle", false}}));
    ASSERT_FALSE(ids.back().empty()) << daemon.stderrTail();
    ASSERT_EQ(finishScan(client, ids.back()).value("state", ""), "done");
  }
  const json list = client.get("/api/v1/scans").json();
  ASSERT_EQ(list.size(), 2u) << list.dump();
  EXPECT_EQ(list[0].value("id", ""), ids[2]);
  EXPECT_EQ(list[1].value("id", ""), ids[1]);
  EXPECT_EQ(client.get("/api/v1/scans/" + ids[0]).status, 404);
  EXPECT_EQ(client.get("/api/v1/scans/" + ids[1] + "/cloud.ply").status, 200);
  daemon.stop();
}

TEST(DaemonScan, AnotherSceneOfTheBoard) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  const std::string id = startScan(
      client, {{"scene", "isolated_objects.toml"}, {"frames", 10}, {"save_bundle", false}});
  ASSERT_FALSE(id.empty()) << daemon.stderrTail();
  const json scan = finishScan(client, id);
  ASSERT_EQ(scan.value("state", ""), "done") << scan.dump() << daemon.stderrTail();
  EXPECT_EQ(scan.at("options").value("scene", ""), "isolated_objects.toml");
  // Not the default scene: far fewer points lie on its sphere and backdrop.
  const auto ply = client.get("/api/v1/scans/" + id + "/cloud.ply");
  ASSERT_EQ(ply.status, 200) << ply.describe();
  const CloudCheck check = checkCloud(formats::readPly(daemon.dir().write("other.ply", ply.body)));
  std::cout << "[daemon e2e] isolated_objects: " << check.points << " points, " << check.outliers
            << " off the default scene's surfaces\n";
  EXPECT_GT(check.points, 1000u);
  EXPECT_GT(static_cast<double>(check.outliers), 0.5 * static_cast<double>(check.points));
  daemon.stop();
}

}  // namespace
}  // namespace cylscan::test
