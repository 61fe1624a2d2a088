// SPDX-License-Identifier: Apache-2.0
// The daemon's 360° head on a small ring board: head.json is
// validated against the board before it is installed, survives a restart, and
// the status lists the cameras; a ring scan lists every camera with the
// reason its cloud is missing.
#include <chrono>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "firmware/daemon/scan_service.hpp"
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
    ScanServiceOptions o;
    o.board = board;
    o.data_dir = data_dir.path();
    o.version = "test";
    return o;
  }
};

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

}  // namespace
}  // namespace cylscan::firmware
