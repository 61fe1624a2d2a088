// SPDX-License-Identifier: Apache-2.0
// The daemon's 360° head on a small ring board: head.json is
// validated against the board before it is installed, survives a restart, and
// the status lists the cameras; a ring scan lists every camera with the
// reason its cloud is missing, and one whose calibration is damaged fails
// without leaving any file.
#include <chrono>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "algo/quasi_calibration.hpp"
#include "firmware/daemon/scan_service.hpp"
#include "tests/daemon/service_test_support.hpp"
#include "tests/support/ring_board.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using nlohmann::json;
using test_support::TempDir;

const char* kIdentity = R"({"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]})";

std::string headJson(const std::string& other_camera) {
  return std::string(
             R"({"format": "cylscan-head-1", "frame": "main", "method": "turntable", "cameras": {"main": )") +
         kIdentity + ", \"" + other_camera +
         R"(": {"R": [[0,0,1],[0,1,0],[-1,0,0]], "T": [120,0,120]}}, "rms_mm": 0.02})";
}

struct RingHead {
  TempDir board_dir, data_dir;
  fs::path board = test_support::ringBoard(board_dir);
  ScanServiceOptions options() const {
    return test_support::serviceOptions(board, data_dir.path());
  }
};

// Valid at every pixel of a 160×128 camera, over any scan's phase.
std::string everywhereCalibration() {
  const cv::Size size(160, 128);
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(size.area()), 1);
  std::vector<algo::PixelPolynomial> pixels(valid.size());
  for (algo::PixelPolynomial& p : pixels) {
    p.phase_inv_half = 1e-4f;
    p.z[0] = 600.0f;
  }
  algo::QuasiCalibrationInfo info;
  info.pose_count = 8;
  info.min_poses = 6;
  const auto bytes =
      algo::QuasiCalibration(size, std::move(valid), std::move(pixels), info).serialize();
  return std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

template <typename F>
int statusOf(F&& f) {
  try {
    f();
  } catch (const ServiceError& e) {
    return e.httpStatus();
  }
  return 0;
}

TEST(HeadExtrinsicsService, InstallsAValidHeadAndKeepsItAcrossARestart) {
  RingHead head;
  {
    ScanService service(head.options());
    EXPECT_FALSE(service.headInfo());
    EXPECT_EQ(service.status()["head"]["installed"], false);
    const json info = service.installHead(headJson("cam90"));
    EXPECT_EQ(info["cameras"]["cam90"]["T"][0], 120.0);
    EXPECT_TRUE(fs::exists(head.data_dir.path() / "calibration" / "head.json"));
    EXPECT_EQ(service.status()["head"]["installed"], true);
    service.stop();
  }
  ScanService again(head.options());
  ASSERT_TRUE(again.headInfo());
  EXPECT_EQ((*again.headInfo())["rms_mm"], 0.02);
}

TEST(HeadExtrinsicsService, RefusesCamerasTheBoardDoesNotHave) {
  RingHead head;
  ScanService service(head.options());
  EXPECT_EQ(statusOf([&] { service.installHead(headJson("cam45")); }), 422);
  EXPECT_EQ(statusOf([&] { service.installHead("{\"format\": \"cylscan-head-1\"}"); }), 400);
  EXPECT_EQ(statusOf([&] { service.installHead("not json"); }), 400);
  EXPECT_FALSE(service.headInfo());
  EXPECT_FALSE(fs::exists(head.data_dir.path() / "calibration" / "head.json"));
}

TEST(HeadExtrinsicsService, StatusListsTheCamerasOfARingBoard) {
  RingHead head;
  ScanService service(head.options());
  const json cameras = service.status()["cameras"];
  ASSERT_EQ(cameras.size(), 4u);
  for (const json& c : cameras) {
    EXPECT_EQ(c["scanned"], true) << c;
    EXPECT_EQ(c["calibrated"], false) << c;
  }
  EXPECT_EQ(cameras[1]["name"], "cam90");
}

TEST(HeadExtrinsicsService, AnUncalibratedRingScanListsEveryCameraAndNoCloud) {
  RingHead head;
  ScanService service(head.options());
  const std::string id = service.startScan(json::object());
  ASSERT_TRUE(service.waitUntilIdle(300s));
  const json scan = *service.scan(id);
  ASSERT_EQ(scan["state"], "done") << scan.dump();
  ASSERT_EQ(scan["cameras"].size(), 4u);
  for (const json& c : scan["cameras"])
    EXPECT_EQ(c["calibrated"], false) << c;
  EXPECT_EQ(scan["cloud"], "none");
  EXPECT_FALSE(service.scanFile(id, "cloud.ply"));
  EXPECT_FALSE(service.scanCameraCloud(id, "cam90"));
}

TEST(HeadExtrinsicsService, ARingCameraDamagedOnDiskFailsTheScanAndLeavesNoFile) {
  RingHead head;
  ScanService service(head.options());
  service.installCalibration("main", everywhereCalibration());
  service.installCalibration("cam90", everywhereCalibration());
  const std::string good = service.startScan(json::object());
  ASSERT_TRUE(service.waitUntilIdle(300s));
  const json scan = *service.scan(good);
  ASSERT_EQ(scan["state"], "done") << scan.dump();
  EXPECT_EQ(scan["cloud"], "main");  // no head.json
  EXPECT_EQ(scan["cameras"][1],
            json({{"camera", "cam90"},
                  {"calibrated", true},
                  {"points", scan["cameras"][1]["points"]},
                  {"phase", "fused"},
                  {"phase_valid_fraction", scan["cameras"][1]["phase_valid_fraction"]},
                  {"file", "clouds/cam90.ply"}}));
  EXPECT_GT(scan["cameras"][1]["points"].get<std::size_t>(), 1000u);
  EXPECT_TRUE(service.scanCameraCloud(good, "cam90"));

  {
    std::ofstream out(head.data_dir.path() / "calibration" / "cam90.qcal", std::ios::trunc);
    out << "not a calibration any more";
  }
  const std::string id = service.startScan(json::object());
  ASSERT_TRUE(service.waitUntilIdle(300s));
  const json failed = *service.scan(id);
  EXPECT_EQ(failed["state"], "failed") << failed.dump();
  EXPECT_NE(failed["error"].get<std::string>().find("cam90.qcal"), std::string::npos)
      << failed.dump();
  EXPECT_EQ(failed["files"], json::array());
  // Main's files were made before cam90's turn: only the record is left.
  std::vector<std::string> left;
  for (const auto& e : fs::recursive_directory_iterator(service.store().scansDir() / id))
    left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"scan.json"});
  EXPECT_FALSE(fs::exists(service.store().scansDir() / (".partial-" + id)));
  // cam90 shows uncalibrated until it is installed again; main still is.
  const json cameras = service.status()["cameras"];
  EXPECT_EQ(cameras[0]["calibrated"], true) << cameras;
  EXPECT_EQ(cameras[1]["calibrated"], false) << cameras;
  EXPECT_EQ(service.status()["last_error"], failed["error"]);
}

}  // namespace
}  // namespace cylscan::firmware
