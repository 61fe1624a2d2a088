// SPDX-License-Identifier: Apache-2.0
// The daemon's service on a small virtual head: a scan runs to done with its
// progress and files, one scan at a time, options checked, a failed scan is
// recorded without losing the others, shutdown aborts a scan safely, and a
// calibration is validated before it replaces the installed one.
#include "firmware/daemon/scan_service.hpp"

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "algo/quasi_calibration.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "formats/images.hpp"
#include "formats/png.hpp"
#include "formats/point_cloud.hpp"
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
constexpr auto kScanWait = 300s;

struct Head {
  TempDir board_dir, data_dir;
  fs::path board;
  explicit Head(const std::vector<std::pair<std::string, std::string>>& replace = {})
      : board(smallBoard(board_dir, test_support::kWallScene, replace)) {}
  ScanServiceOptions options() const {
    return test_support::serviceOptions(board, data_dir.path());
  }
};

// Events until the scan `id` is done or failed (or the wait ends).
std::vector<HeadEvent> eventsUntilFinished(EventStream& stream, const std::string& id) {
  std::vector<HeadEvent> events;
  const auto deadline = std::chrono::steady_clock::now() + kScanWait;
  while (std::chrono::steady_clock::now() < deadline) {
    auto e = stream.next(1s);
    if (!e) {
      if (stream.closed()) break;
      continue;
    }
    events.push_back(*e);
    if (e->name == "scan" && e->data["id"] == id &&
        (e->data["state"] == "done" || e->data["state"] == "failed"))
      break;
  }
  return events;
}

// A calibration for the 160×128 head: every pixel valid, X = u, Y = v,
// Z = 600 + 10·t over a phase range far wider than the scan's (|t| < 0.1).
algo::QuasiCalibration syntheticCalibration(cv::Size size) {
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(size.area()), 1);
  std::vector<algo::PixelPolynomial> pixels(valid.size());
  for (int v = 0; v < size.height; ++v) {
    for (int u = 0; u < size.width; ++u) {
      algo::PixelPolynomial& p = pixels[static_cast<std::size_t>(v * size.width + u)];
      p.phase_centre = 0.0f;
      p.phase_inv_half = 1e-4f;
      p.x[0] = static_cast<float>(u);
      p.y[0] = static_cast<float>(v);
      p.z[0] = 600.0f;
      p.z[1] = 10.0f;
    }
  }
  algo::QuasiCalibrationInfo info;
  info.pose_count = 8;
  info.min_poses = 6;
  return algo::QuasiCalibration(size, std::move(valid), std::move(pixels), info);
}

std::string bytesOf(const algo::QuasiCalibration& calib) {
  const auto bytes = calib.serialize();
  return std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

std::string fileText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(ScanService, AScanRunsToDoneWithProgressInOrderAndItsFiles) {
  Head head;
  ScanService service(head.options());
  EXPECT_EQ(service.status()["state"], "idle");
  EXPECT_EQ(service.status()["board"], service.boardName());
  auto stream = service.subscribe();
  const std::string id = service.startScan({{"frames", 5}, {"save_bundle", false}});
  EXPECT_TRUE(isValidScanId(id)) << id;
  const std::vector<HeadEvent> events = eventsUntilFinished(*stream, id);
  ASSERT_FALSE(events.empty());

  // On connect the state; then the scan queued, scanning, running, every
  // frame in order, the scan done, idle.
  EXPECT_EQ(events.front().name, "state");
  EXPECT_EQ(events.front().data["state"], "idle");
  int last_done = 0;
  std::vector<std::string> states;
  for (std::size_t i = 0; i < events.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(events[i].seq, events[i - 1].seq);
    }
    const HeadEvent& e = events[i];
    if (e.name == "progress") {
      EXPECT_EQ(e.data["id"], id);
      EXPECT_EQ(e.data["frames_total"], 10);
      EXPECT_EQ(e.data["frames_done"], last_done + 1);
      last_done = e.data["frames_done"];
      EXPECT_NEAR(e.data["progress"].get<double>(), last_done / 10.0, 1e-9);
    }
    if (e.name == "scan") states.push_back(e.data["state"]);
  }
  EXPECT_EQ(last_done, 10);
  EXPECT_EQ(states, (std::vector<std::string>{"queued", "running", "done"}));
  ASSERT_TRUE(service.waitUntilIdle(kScanWait));

  const auto scan = service.scan(id);
  ASSERT_TRUE(scan);
  EXPECT_EQ((*scan)["state"], "done");
  EXPECT_EQ((*scan)["frames"], 10);
  EXPECT_EQ((*scan)["frames_done"], 10);
  EXPECT_EQ((*scan)["calibrated"], false);
  EXPECT_EQ((*scan)["options"], json({{"frames", 5}, {"save_bundle", false}}));
  EXPECT_GT((*scan)["phase_valid_fraction"].get<double>(), 0.5);
  EXPECT_EQ((*scan)["files"], json({"texture.png", "phase.png"}));
  for (const char* name : {"texture.png", "phase.png", "scan.json"}) {
    const auto file = service.scanFile(id, name);
    ASSERT_TRUE(file) << name;
    EXPECT_TRUE(fs::is_regular_file(*file));
  }
  const cv::Mat phase = formats::readPng(*service.scanFile(id, "phase.png"));
  EXPECT_EQ(phase.size(), cv::Size(160, 128));
  EXPECT_EQ(phase.channels(), 3);
  EXPECT_FALSE(service.scanFile(id, "cloud.ply"));  // uncalibrated
  EXPECT_FALSE(service.scanFile(id, "../scan.json"));
  EXPECT_FALSE(fs::exists(service.store().scansDir() / id / "bundle"));

  const json status = service.status();
  EXPECT_EQ(status["state"], "idle");
  EXPECT_EQ(status["scans"], 1);
  EXPECT_TRUE(status["current_scan"].is_null());
  EXPECT_EQ(service.listScans().size(), 1u);

  const std::string metrics = service.metricsText();
  EXPECT_NE(metrics.find("cylscan_scans_total{result=\"done\"} 1\n"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("cylscan_scans_total{result=\"failed\"} 0\n"), std::string::npos);
  EXPECT_NE(metrics.find("cylscan_frames_total 10\n"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("cylscan_step_lateness_seconds_count"), std::string::npos);
}

TEST(ScanService, OneScanAtATime) {
  Head head;
  ScanService service(head.options());
  const std::string id = service.startScan({{"frames", 200}});
  const ServiceError second = errorOf([&] { service.startScan(json::object()); });
  EXPECT_EQ(second.httpStatus(), 409);
  EXPECT_NE(std::string(second.what()).find(id), std::string::npos) << second.what();
  EXPECT_EQ(errorOf([&] { service.deleteScan(id); }).httpStatus(), 409);
  EXPECT_EQ(service.status()["state"], "scanning");
  EXPECT_EQ(service.status()["current_scan"], id);
  EXPECT_FALSE(service.scanFile(id, "texture.png"));  // not done yet
  ASSERT_TRUE(service.waitUntilIdle(kScanWait));
  EXPECT_EQ((*service.scan(id))["state"], "done");
  // Done: it can be deleted, and another scan started.
  EXPECT_TRUE(service.deleteScan(id));
  EXPECT_FALSE(service.scan(id));
  EXPECT_FALSE(service.deleteScan(id));
  EXPECT_FALSE(fs::exists(service.store().scansDir() / id));
}

TEST(ScanService, BadOptionsAre400NamingTheKey) {
  Head head;
  fs::create_directories(head.board / "scenes");
  ScanService service(head.options());
  const std::pair<json, std::string> cases[] = {
      {{{"framez", 5}}, "framez"},
      {{{"frames", 2}}, "frames"},
      {{{"frames", 1001}}, "frames"},
      {{{"frames", "5"}}, "frames"},
      {{{"frames", 5.5}}, "frames"},
      {{{"mode", "fast"}}, "mode"},
      {{{"save_bundle", 1}}, "save_bundle"},
      {{{"phase", "low"}}, "phase"},
      {{{"scene", "../board.toml"}}, "scene"},
      {{{"scene", "sub/x.toml"}}, "scene"},
      {{{"scene", "missing.toml"}}, "scene"},
      {{{"scene", 3}}, "scene"},
      {json::array({1, 2}), "options"},
      {json("stop"), "options"},
  };
  for (const auto& [options, key] : cases) {
    const ServiceError e = errorOf([&] { service.startScan(options); });
    EXPECT_EQ(e.httpStatus(), 400) << options.dump();
    EXPECT_EQ(std::string(e.what()).substr(0, key.size() + 1), key + ":")
        << options.dump() << " -> " << e.what();
  }
  EXPECT_TRUE(service.listScans().empty());
  EXPECT_EQ(service.status()["state"], "idle");
}

TEST(ScanService, ASceneOfTheBoardAndASavedBundle) {
  Head head;
  fs::create_directories(head.board / "scenes");
  std::ofstream(head.board / "scenes/near.toml")
      << "name = \"near\"\n[[object]]\ntype = \"plane\"\npoint = [0.0, 0.0, 520.0]\n"
         "normal = [0.0, 0.0, -1.0]\n";
  ScanService service(head.options());
  const std::string id =
      service.startScan({{"frames", 4}, {"scene", "near.toml"}, {"save_bundle", true}});
  ASSERT_TRUE(service.waitUntilIdle(kScanWait));
  const json scan = *service.scan(id);
  ASSERT_EQ(scan["state"], "done") << scan.dump();
  EXPECT_TRUE(fs::exists(service.store().scansDir() / id / "bundle/capture.json"));
  // Back on the default scene without the option.
  const std::string next = service.startScan({{"frames", 4}});
  ASSERT_TRUE(service.waitUntilIdle(kScanWait));
  EXPECT_EQ((*service.scan(next))["state"], "done");
}

TEST(ScanService, AFailedScanIsRecordedAndNoEarlierScanLost) {
  Head good;
  std::string first;
  {
    ScanService service(good.options());
    first = service.startScan({{"frames", 4}});
    ASSERT_TRUE(service.waitUntilIdle(kScanWait));
    ASSERT_EQ((*service.scan(first))["state"], "done");
  }
  // The same data directory on a head whose home switch never fires: the
  // stage starts 200° away from home and may travel only 90° to find it.
  Head bad(std::vector<std::pair<std::string, std::string>>{
      {"home_max_travel_deg = 370.0", "home_max_travel_deg = 90.0"}});
  std::ofstream(bad.board / "board.toml", std::ios::app)
      << "[sim.head.stage]\ninitial_deg = 200.0\n";
  ScanServiceOptions options = bad.options();
  options.data_dir = good.data_dir.path();
  ScanService service(options);
  auto stream = service.subscribe();
  const std::string id = service.startScan({{"frames", 4}});
  const auto events = eventsUntilFinished(*stream, id);
  ASSERT_TRUE(service.waitUntilIdle(kScanWait));
  const json scan = *service.scan(id);
  EXPECT_EQ(scan["state"], "failed");
  EXPECT_NE(scan["error"].get<std::string>().find("home switch never fired"), std::string::npos)
      << scan.dump();
  EXPECT_EQ(scan["files"], json::array());
  bool error_event = false;
  for (const auto& e : events)
    error_event |= e.name == "error" && e.data["id"] == id && e.data["error"] == scan["error"];
  EXPECT_TRUE(error_event);

  const json status = service.status();
  EXPECT_EQ(status["state"], "error");
  EXPECT_EQ(status["last_error"], scan["error"]);
  const json list = service.listScans();
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0]["id"], id);  // newest first
  EXPECT_EQ(list[1]["id"], first);
  EXPECT_EQ(list[1]["state"], "done");
  EXPECT_TRUE(service.scanFile(first, "phase.png"));
  EXPECT_NE(service.metricsText().find("cylscan_scans_total{result=\"failed\"} 1\n"),
            std::string::npos);
  service.stop();
  drivers::Board* board = service.boardAfterStop();
  ASSERT_NE(board, nullptr);
  EXPECT_FALSE(board->virtualHead()->lightOn());
  EXPECT_FALSE(board->virtualHead()->stage().enabled());
}

TEST(ScanService, ShutdownDuringAScanAbortsItCleanly) {
  Head head;
  ScanService service(head.options());
  auto stream = service.subscribe();
  const std::string id = service.startScan({{"frames", 200}});
  // Wait for the first frame: the scan is running.
  bool running = false;
  for (int i = 0; i < 300 && !running; ++i) {
    auto e = stream->next(1s);
    running = e && e->name == "progress";
  }
  ASSERT_TRUE(running);
  service.stop();
  const json scan = *service.scan(id);
  EXPECT_EQ(scan["state"], "failed");
  EXPECT_EQ(scan["error"], "aborted: daemon stopping");
  EXPECT_LT(scan["frames_done"].get<int>(), 400);
  EXPECT_TRUE(fs::exists(service.store().scansDir() / id / "scan.json"));
  drivers::Board* board = service.boardAfterStop();
  ASSERT_NE(board, nullptr);
  EXPECT_FALSE(board->virtualHead()->lightOn());
  EXPECT_FALSE(board->virtualHead()->stage().enabled());
  EXPECT_EQ(errorOf([&] { service.startScan(json::object()); }).httpStatus(), 503);
  // The event streams end.
  for (int i = 0; i < 10000 && !stream->closed(); ++i)
    stream->next(0ms);
  EXPECT_TRUE(stream->closed());
  // A new service on the data directory finds the failed scan.
  ScanServiceOptions options = head.options();
  ScanService again(options);
  ASSERT_TRUE(again.scan(id));
  EXPECT_EQ((*again.scan(id))["state"], "failed");
}

TEST(ScanService, RetentionKeepsTheNewestScans) {
  Head head;
  ScanServiceOptions options = head.options();
  options.retention = {2, 0};
  ScanService service(options);
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    ids.push_back(service.startScan({{"frames", 3}}));
    ASSERT_TRUE(service.waitUntilIdle(kScanWait));
    ASSERT_EQ((*service.scan(ids.back()))["state"], "done");
  }
  const json list = service.listScans();
  ASSERT_EQ(list.size(), 2u) << list.dump();
  EXPECT_EQ(list[0]["id"], ids[2]);
  EXPECT_EQ(list[1]["id"], ids[1]);
  EXPECT_FALSE(service.scan(ids[0]));
  EXPECT_FALSE(fs::exists(service.store().scansDir() / ids[0]));
  EXPECT_EQ(service.status()["scans"], 2);
}

TEST(ScanService, NoRoomOnTheDiskIs507) {
  Head head;
  ScanServiceOptions options = head.options();
  options.free_space_margin_bytes = std::uint64_t{1} << 62;
  ScanService service(options);
  const ServiceError e = errorOf([&] { service.startScan(json::object()); });
  EXPECT_EQ(e.httpStatus(), 507);
  EXPECT_TRUE(service.listScans().empty());
  // The estimate grows with a saved bundle (frames × pixels).
  EXPECT_EQ(service.scanEstimateBytes({{"frames", 10}, {"save_bundle", true}}) -
                service.scanEstimateBytes({{"frames", 10}, {"save_bundle", false}}),
            20u * 160 * 128);
}

TEST(ScanService, ACalibrationIsCheckedBeforeItReplacesTheInstalledOne) {
  Head head;
  ScanServiceOptions options = head.options();
  const std::string good = bytesOf(syntheticCalibration({160, 128}));
  options.max_calibration_bytes = good.size();
  ScanService service(options);
  EXPECT_EQ(service.calibrationInfo("main")["installed"], false);
  EXPECT_FALSE(service.calibrationFile("main"));

  const json info = service.installCalibration("main", good);
  EXPECT_EQ(info["installed"], true);
  EXPECT_EQ(info["width"], 160);
  EXPECT_EQ(info["height"], 128);
  EXPECT_EQ(info["phase_source"], "fused");
  EXPECT_EQ(info["bytes"], good.size());
  EXPECT_EQ(service.calibrationInfo("main"), info);
  ASSERT_TRUE(service.calibrationFile("main"));
  EXPECT_EQ(fileText(*service.calibrationFile("main")), good);
  EXPECT_EQ(service.status()["calibration"]["main"], true);

  const std::pair<std::string, int> bad[] = {
      {"not a calibration at all", 400},
      {good.substr(0, good.size() / 2), 400},  // truncated
      {bytesOf(syntheticCalibration({80, 64})), 422},
      {good + "x", 413},
  };
  std::string corrupt = good;
  corrupt[corrupt.size() - 7] ^= 0x55;  // the CRC catches it
  for (const auto& [bytes, status] : bad) {
    EXPECT_EQ(errorOf([&] { service.installCalibration("main", bytes); }).httpStatus(), status);
    EXPECT_EQ(fileText(*service.calibrationFile("main")), good);  // untouched
  }
  EXPECT_EQ(errorOf([&] { service.installCalibration("main", corrupt); }).httpStatus(), 400);
  EXPECT_EQ(errorOf([&] { service.installCalibration("nope", good); }).httpStatus(), 400);
  EXPECT_EQ(fileText(*service.calibrationFile("main")), good);
  // Asking for the other phase than the calibration's is refused.
  EXPECT_EQ(errorOf([&] { service.startScan({{"phase", "high"}}); }).httpStatus(), 400);

  // A calibrated scan: the cloud has a point for every valid phase pixel
  // (the synthetic calibration is valid everywhere, within its range).
  const std::string id = service.startScan({{"frames", 5}});
  ASSERT_TRUE(service.waitUntilIdle(kScanWait));
  const json scan = *service.scan(id);
  ASSERT_EQ(scan["state"], "done") << scan.dump();
  EXPECT_EQ(scan["calibrated"], true);
  EXPECT_EQ(scan["files"],
            json({"cloud.ply", "depth.tiff", "texture.png", "phase.png", "depth.png"}));
  const std::size_t points = scan["points"];
  EXPECT_NEAR(static_cast<double>(points), scan["phase_valid_fraction"].get<double>() * 160 * 128,
              0.5);
  const formats::PointCloud cloud = formats::readPly(*service.scanFile(id, "cloud.ply"));
  EXPECT_EQ(cloud.size(), points);
  const cv::Mat depth = formats::readFloatTiff(*service.scanFile(id, "depth.tiff"));
  std::size_t finite = 0;
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 0; u < depth.cols; ++u) {
      const float z = depth.at<float>(v, u);
      if (!std::isfinite(z)) continue;
      ++finite;
      EXPECT_NEAR(z, 600.0f, 1.0f);  // 600 + 10·t, |t| < 0.1
    }
  EXPECT_EQ(finite, points);
  const cv::Mat preview = formats::readPng(*service.scanFile(id, "depth.png"));
  EXPECT_EQ(preview.size(), depth.size());
}

}  // namespace
}  // namespace cylscan::firmware
