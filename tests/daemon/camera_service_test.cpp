// SPDX-License-Identifier: Apache-2.0
// The cameras of the daemon's service on a small virtual head: their
// controls and ranges, a PATCH checked, kept across a restart and seen in
// the picture, the live view's pictures, and the live view giving way to a
// scan.
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "firmware/daemon/scan_service.hpp"
#include "tests/daemon/service_test_support.hpp"
#include "tests/support/small_board.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using nlohmann::json;
using test_support::errorOf;
using test_support::smallBoard;
using test_support::TempDir;

// Generous bounds on waits for the virtual head (not timing assertions).
constexpr auto kPictureWait = 30s;
constexpr auto kScanWait = 300s;

struct Head {
  TempDir board_dir, data_dir;
  fs::path board = smallBoard(board_dir, test_support::kWallScene);
  ScanServiceOptions options() const {
    return test_support::serviceOptions(board, data_dir.path());
  }
};

json cameraNamed(const json& cameras, const std::string& name) {
  for (const json& c : cameras)
    if (c.at("name") == name) return c;
  return nullptr;
}

// The next picture of a live view, decoded.
cv::Mat nextPicture(LiveStream& live, LiveFrame* frame = nullptr) {
  auto f = live.next(std::chrono::duration_cast<std::chrono::milliseconds>(kPictureWait));
  if (!f) return {};
  if (frame != nullptr) *frame = *f;
  const std::vector<unsigned char> bytes(f->jpeg.begin(), f->jpeg.end());
  return cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
}

TEST(CameraService, ListsEveryCameraWithItsRanges) {
  Head head;
  ScanService service(head.options());
  const json cameras = service.cameras();
  ASSERT_EQ(cameras.size(), service.status()["cameras"].size());
  const json main = cameraNamed(cameras, "main");
  ASSERT_TRUE(main.is_object()) << cameras;
  EXPECT_GT(main["width"].get<int>(), 0);
  EXPECT_EQ(main["calibrated"], false);
  for (const char* key : {"exposure_us", "gain"}) {
    const json& c = main["controls"][key];
    EXPECT_LE(c["min"].get<double>(), c["value"].get<double>()) << key;
    EXPECT_LE(c["value"].get<double>(), c["max"].get<double>()) << key;
    EXPECT_LT(c["min"].get<double>(), c["max"].get<double>()) << key;
  }
  // Every camera's calibration state is in the status.
  const json status = service.status();
  for (const json& c : cameras)
    EXPECT_EQ(status["calibration"][c["name"].get<std::string>()], false) << status;
}

TEST(CameraService, PatchIsCheckedAndKeptAcrossARestart) {
  Head head;
  double exposure = 0;
  {
    ScanService service(head.options());
    const json range = cameraNamed(service.cameras(), "main")["controls"]["exposure_us"];
    auto e = errorOf([&] {
      service.setCameraControls("main", {{"exposure_us", range["max"].get<double>() * 2}});
    });
    EXPECT_EQ(e.httpStatus(), 400);
    EXPECT_NE(std::string(e.what()).find("exposure_us"), std::string::npos) << e.what();
    e = errorOf([&] { service.setCameraControls("main", {{"gain", "high"}}); });
    EXPECT_EQ(e.httpStatus(), 400);
    EXPECT_NE(std::string(e.what()).find("gain"), std::string::npos) << e.what();
    e = errorOf([&] { service.setCameraControls("main", {{"iso", 100}}); });
    EXPECT_EQ(e.httpStatus(), 400);
    EXPECT_EQ(errorOf([&] { service.setCameraControls("nope", {{"gain", 2}}); }).httpStatus(), 404);
    // Nothing refused was kept.
    EXPECT_FALSE(fs::exists(head.data_dir.path() / "cameras.json"));

    exposure = range["value"].get<double>() / 2;
    const json answer = service.setCameraControls("main", {{"exposure_us", exposure}});
    EXPECT_DOUBLE_EQ(answer["controls"]["exposure_us"]["value"].get<double>(), exposure);
  }
  ScanService restarted(head.options());
  EXPECT_DOUBLE_EQ(
      cameraNamed(restarted.cameras(), "main")["controls"]["exposure_us"]["value"].get<double>(),
      exposure);
}

TEST(CameraService, AnUnreadableSettingsFileLeavesTheProfilesValues) {
  Head head;
  double profile_exposure = 0;
  {
    ScanService service(head.options());
    profile_exposure =
        cameraNamed(service.cameras(), "main")["controls"]["exposure_us"]["value"].get<double>();
  }
  std::ofstream(head.data_dir.path() / "cameras.json") << "{\"main\": {\"exposure_us\": -3}}";
  ScanService service(head.options());
  EXPECT_DOUBLE_EQ(
      cameraNamed(service.cameras(), "main")["controls"]["exposure_us"]["value"].get<double>(),
      profile_exposure);
}

TEST(CameraService, LiveViewShowsTheExposureAndGivesWayToAScan) {
  Head head;
  ScanService service(head.options());
  const json main = cameraNamed(service.cameras(), "main");
  const double exposure = main["controls"]["exposure_us"]["value"].get<double>();

  auto live = service.openLiveView({"main", false});
  LiveFrame frame;
  const cv::Mat before = nextPicture(*live, &frame);
  ASSERT_FALSE(before.empty());
  EXPECT_EQ(before.cols, main["width"].get<int>());
  EXPECT_EQ(before.rows, main["height"].get<int>());
  EXPECT_EQ(frame.sequence, 1u);
  EXPECT_GE(frame.saturated, 0.0);
  EXPECT_GT(frame.focus, 0.0);  // the lit wall has texture and fringes

  // Half the exposure: a picture taken after the PATCH is darker. The scene
  // is far from saturation at the profile's exposure, so the mean about
  // halves; 0.75 leaves room for the sensor's offset and noise.
  service.setCameraControls("main", {{"exposure_us", exposure / 2}});
  auto after_patch = service.openLiveView({"main", false});
  const cv::Mat after = nextPicture(*after_patch);
  ASSERT_FALSE(after.empty());
  EXPECT_LT(cv::mean(after)[0], 0.75 * cv::mean(before)[0]);
  after_patch.reset();

  // With the overlay the picture is in colour.
  auto overlaid = service.openLiveView({"main", true});
  const cv::Mat colour = nextPicture(*overlaid);
  EXPECT_EQ(colour.channels(), 3);
  overlaid.reset();

  // A scan ends the live view (409), and while it runs neither a live view
  // nor a PATCH is taken.
  const std::string id = service.startScan(json::object());
  const auto deadline = std::chrono::steady_clock::now() + kPictureWait;
  while (!live->ended() && std::chrono::steady_clock::now() < deadline)
    live->next(100ms);
  ASSERT_TRUE(live->ended());
  EXPECT_EQ(live->endStatus(), 409);
  EXPECT_NE(live->endReason().find("scan"), std::string::npos);
  if (!service.waitUntilIdle(1ms)) {
    EXPECT_EQ(errorOf([&] { service.openLiveView({"main", false}); }).httpStatus(), 409);
    EXPECT_EQ(errorOf([&] { service.setCameraControls("main", {{"gain", 2}}); }).httpStatus(), 409);
  }
  ASSERT_TRUE(service.waitUntilIdle(kScanWait));
  EXPECT_EQ(service.scan(id).value()["state"], "done");

  // The live view comes back after the scan.
  auto again = service.openLiveView({"main", false});
  EXPECT_FALSE(nextPicture(*again).empty());
}

TEST(CameraService, StoppingEndsTheLiveView) {
  Head head;
  ScanService service(head.options());
  auto live = service.openLiveView({"main", false});
  EXPECT_EQ(errorOf([&] { service.openLiveView({"nope", false}); }).httpStatus(), 404);
  service.stop();
  EXPECT_TRUE(live->ended());
  EXPECT_EQ(live->endStatus(), 503);
  EXPECT_EQ(errorOf([&] { service.openLiveView({"main", false}); }).httpStatus(), 503);
}

}  // namespace
}  // namespace cylscan::firmware
