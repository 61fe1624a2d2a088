// SPDX-License-Identifier: Apache-2.0
// The daemon's 360° outputs on the calibrated virtual head (fixture.ring_head):
// with the four calibrations and the extrinsics installed, a ring scan's
// cloud.ply is the merged cloud of all four cameras in the head frame and
// clouds/<camera>.ply each camera's; without head.json, main's alone and why.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "algo/surface_fit.hpp"
#include "firmware/daemon/scan_service.hpp"
#include "formats/point_cloud.hpp"
#include "tests/cli/cli_support.hpp"

namespace cylscan {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using nlohmann::json;

const fs::path kFixture = CYLSCAN_RING_FIXTURE;
const char* kCameras[] = {"main", "cam90", "cam180", "cam270"};

std::string readBytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class DaemonRing : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kFixture / "ready"))
      FAIL() << "no fixture " << kFixture << " (ctest runs fixture.ring_head first)";
    std::string bundles;
    for (const auto& entry : fs::directory_iterator(kFixture / "turntable")) {
      if (entry.is_directory() && entry.path().filename().string().starts_with("turn"))
        bundles += " " + entry.path().string();
    }
    head_ = work_.path() / "head.json";
    const test::ToolResult r =
        test::runTool("calibrate-head --calib-dir " + (kFixture / "calib").string() + " --out " +
                      head_.string() + bundles);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  firmware::ScanServiceOptions options() const {
    firmware::ScanServiceOptions o;
    o.board = kFixture / "board";
    o.data_dir = data_.path();
    o.version = "test";
    return o;
  }
  json scanOnce(firmware::ScanService& service) {
    const std::string id = service.startScan(json::object());
    EXPECT_TRUE(service.waitUntilIdle(600s));
    return *service.scan(id);
  }

  test::TempDir work_, data_;
  fs::path head_;
};

TEST_F(DaemonRing, ARingScanMergesEveryCalibratedCamera) {
  firmware::ScanService service(options());
  for (const char* camera : kCameras)
    service.installCalibration(camera,
                               readBytes(kFixture / "calib" / (std::string(camera) + ".qcal")));

  // Without head.json: main's cloud alone, and why.
  const json alone = scanOnce(service);
  ASSERT_EQ(alone["state"], "done") << alone.dump();
  EXPECT_EQ(alone["cloud"], "main");
  EXPECT_NE(alone["cloud_note"].get<std::string>().find("PUT /api/v1/head"), std::string::npos);
  const formats::PointCloud main_only =
      formats::readPly(*service.scanFile(alone["id"].get<std::string>(), "cloud.ply"));
  EXPECT_EQ(formats::cameraNamesOf(main_only), (std::vector<std::string>{"main"}));

  service.installHead(readBytes(head_));
  const json scan = scanOnce(service);
  ASSERT_EQ(scan["state"], "done") << scan.dump();
  const std::string id = scan["id"];
  EXPECT_EQ(scan["cloud"], "merged");
  ASSERT_EQ(scan["cameras"].size(), 4u);
  std::size_t sum = 0;
  for (const json& c : scan["cameras"]) {
    EXPECT_EQ(c["calibrated"], true) << c;
    // Each camera sees its sphere and box: thousands of points at 320×256.
    EXPECT_GT(c["points"].get<std::size_t>(), 10000u) << c;
    sum += c["points"].get<std::size_t>();
    const auto file = service.scanCameraCloud(id, c["camera"].get<std::string>());
    ASSERT_TRUE(file) << c;
    EXPECT_EQ(formats::readPly(*file).size(), c["points"].get<std::size_t>());
  }
  EXPECT_EQ(scan["points"].get<std::size_t>(), sum);
  const formats::PointCloud merged = formats::readPly(*service.scanFile(id, "cloud.ply"));
  EXPECT_EQ(merged.size(), sum);
  EXPECT_EQ(formats::cameraNamesOf(merged),
            (std::vector<std::string>{"main", "cam90", "cam180", "cam270"}));

  // The merged cloud is in the head frame: each camera's 50 mm sphere where
  // the scene's truth (head frame) has it, to the ~1 mm absolute placement of
  // the per-direction calibrations (tests/cli_ring/ring_head_test.cpp).
  const json truth = json::parse(readBytes(kFixture / "surround" / "truth.json"));
  for (const json& o : truth["scenes"]["surround"]["objects"]) {
    if (o["type"] != "sphere") continue;
    const Eigen::Vector3d c(o["center"][0].get<double>(), o["center"][1].get<double>(),
                            o["center"][2].get<double>());
    algo::Points3d points;
    for (std::size_t i = 0; i < merged.size(); ++i) {
      const Eigen::Vector3d x(merged.xyz[3 * i], merged.xyz[3 * i + 1], merged.xyz[3 * i + 2]);
      if ((x - c).norm() < 54.0) points.push_back(x);
    }
    ASSERT_GT(points.size(), 500u) << o["name"];
    const algo::SphereFit fit = algo::fitSphere(points);
    std::cout << "[ figures  ] daemon " << o["name"].get<std::string>() << ": radius "
              << fit.sphere.radius << " mm, centre error " << (fit.sphere.centre - c).norm()
              << " mm\n";
    EXPECT_LT((fit.sphere.centre - c).norm(), 2.0) << o["name"];
    EXPECT_NEAR(fit.sphere.radius, 50.0, 0.05) << o["name"];
  }
  const json status = service.status();
  EXPECT_EQ(status["head"]["installed"], true);
  service.stop();
}

}  // namespace
}  // namespace cylscan
