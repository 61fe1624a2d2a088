// SPDX-License-Identifier: Apache-2.0
// The scan's output step on the phase of real acquisitions of the small
// virtual heads: the files of a daemon scan and of `cylscan scan`, point
// counts that are the phase's valid pixels, the 360° clouds and their merge,
// and a failure part-way that leaves no file behind.
#include "firmware/scan_output.hpp"

#include <cmath>
#include <fstream>
#include <memory>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/board.hpp"
#include "formats/images.hpp"
#include "formats/png.hpp"
#include "formats/point_cloud.hpp"
#include "tests/support/ring_board.hpp"
#include "tests/support/small_board.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using test_support::TempDir;

// The phase of one acquisition, kept for every test of the suite (the plan
// must outlive the sink).
struct Acquired {
  drivers::Board board;
  ScanOptions options;
  ScanPlan plan;
  PhaseSink phase;

  Acquired(const fs::path& board_dir, const std::vector<std::string>& cameras, int frames)
      : board(drivers::Board::open(board_dir)),
        options(withCameras(scanOptionsFrom(board.profile()), cameras, frames)),
        plan(planScan(options, board.profile().stage)),
        phase(plan, {}) {
    Acquisition acquisition(board);
    acquisition.run(options, plan, phase);
  }
  static ScanOptions withCameras(ScanOptions o, const std::vector<std::string>& cameras,
                                 int frames) {
    o.frames_high = o.frames_low = frames;
    o.cameras = cameras;
    return o;
  }
};

Acquired& mainScan() {
  static TempDir board_dir;
  static Acquired scan(test_support::smallBoard(board_dir, test_support::kWallScene), {"main"}, 5);
  return scan;
}

Acquired& ringScan() {
  static TempDir board_dir;
  static Acquired scan(test_support::ringBoard(board_dir), {"main", "cam90"}, 6);
  return scan;
}

// Valid at every pixel over a phase range far wider than a scan's (|Φ| <
// 10^4): X = u, Y = v, Z = 600 + 10·t.
algo::QuasiCalibration everywhere(cv::Size size, PhaseSource source = PhaseSource::Fused) {
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(size.area()), 1);
  std::vector<algo::PixelPolynomial> pixels(valid.size());
  std::size_t i = 0;
  for (int v = 0; v < size.height; ++v) {
    for (int u = 0; u < size.width; ++u) {
      algo::PixelPolynomial& p = pixels[i++];
      p.phase_inv_half = 1e-4f;
      p.x[0] = static_cast<float>(u);
      p.y[0] = static_cast<float>(v);
      p.z[0] = 600.0f;
      p.z[1] = 10.0f;
    }
  }
  algo::QuasiCalibrationInfo info;
  info.phase_source = source;
  info.pose_count = 8;
  info.min_poses = 6;
  return algo::QuasiCalibration(size, std::move(valid), std::move(pixels), info);
}

void install(const algo::QuasiCalibration& calib, const fs::path& file) {
  const auto bytes = calib.serialize();
  std::ofstream(file, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

std::size_t finitePixels(const cv::Mat& map) {
  std::size_t n = 0;
  for (int v = 0; v < map.rows; ++v)
    for (int u = 0; u < map.cols; ++u)
      n += std::isfinite(map.at<float>(v, u)) ? 1 : 0;
  return n;
}

std::size_t validPixels(const algo::PhaseMaps& maps) {
  return static_cast<std::size_t>(cv::countNonZero(maps.invalid == 0));
}

// Every entry under `dir`, hidden ones too, relative.
std::set<std::string> entries(const fs::path& dir) {
  std::set<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    out.insert(fs::relative(e.path(), dir).string());
  return out;
}

std::string fileText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(ScanOutput, UncalibratedTheDaemonGetsThePreviewsAlone) {
  Acquired& scan = mainScan();
  const algo::PhaseMaps maps = scan.phase.finalize("main");
  TempDir out;
  ScanOutputOptions options;
  options.phase = PhaseSource::High;
  const ScanResult result = writeScanOutput(scan.phase, {}, options, out.path());
  EXPECT_EQ(result.files, (std::vector<std::string>{"texture.png", "phase.png"}));
  EXPECT_EQ(entries(out.path()), (std::set<std::string>{"texture.png", "phase.png"}));
  EXPECT_FALSE(result.calibrated);
  EXPECT_FALSE(result.figures.points);
  EXPECT_FALSE(result.figures.ring);
  EXPECT_EQ(result.figures.phase, PhaseSource::High);
  EXPECT_EQ(result.figures.phase_valid_fraction, maps.valid_fraction);
  EXPECT_GT(maps.valid_fraction, 0.5);
  const cv::Mat texture = formats::readPng(out.path() / "texture.png");
  EXPECT_EQ(texture.size(), cv::Size(160, 128));
  EXPECT_EQ(texture.channels(), 1);
}

TEST(ScanOutput, CalibratedEveryValidPixelIsAPointOfTheCloudAndTheDepth) {
  Acquired& scan = mainScan();
  const algo::PhaseMaps maps = scan.phase.finalize("main");
  TempDir out;
  ScanCalibrations calibrations;
  calibrations.main = everywhere({160, 128});
  const ScanResult result = writeScanOutput(scan.phase, calibrations, {}, out.path());
  const std::vector<std::string> files = {"cloud.ply", "depth.tiff", "texture.png", "phase.png",
                                          "depth.png"};
  EXPECT_EQ(result.files, files);
  EXPECT_EQ(entries(out.path()), std::set<std::string>(files.begin(), files.end()));
  EXPECT_TRUE(result.calibrated);
  EXPECT_EQ(result.figures.phase, PhaseSource::Fused);
  ASSERT_TRUE(result.figures.points);
  const std::size_t points = *result.figures.points;
  EXPECT_EQ(points, validPixels(maps));
  EXPECT_EQ(points, finitePixels(maps.fused));
  EXPECT_NEAR(static_cast<double>(points), maps.valid_fraction * 160 * 128, 0.5);
  EXPECT_EQ(formats::readPly(out.path() / "cloud.ply").size(), points);
  const cv::Mat depth = formats::readFloatTiff(out.path() / "depth.tiff");
  EXPECT_EQ(finitePixels(depth), points);
  EXPECT_EQ(formats::readPng(out.path() / "depth.png").size(), depth.size());
}

TEST(ScanOutput, TheCommandLinesCloudWhereItIsAskedWithThePhaseAskedFor) {
  Acquired& scan = mainScan();
  const algo::PhaseMaps maps = scan.phase.finalize("main");
  TempDir out;
  ScanCalibrations calibrations;
  calibrations.main = everywhere({160, 128});
  ScanOutputOptions options;
  options.phase = PhaseSource::High;
  options.cloud = (out.path() / "scan.ply").string();  // absolute: used as it is
  options.depth = "";
  options.previews = false;
  const ScanResult result = writeScanOutput(scan.phase, calibrations, options, {});
  EXPECT_EQ(result.files, std::vector<std::string>{options.cloud});
  EXPECT_EQ(entries(out.path()), std::set<std::string>{"scan.ply"});
  ASSERT_TRUE(result.figures.points);
  EXPECT_EQ(*result.figures.points, finitePixels(maps.absolute));
  EXPECT_EQ(formats::readPly(out.path() / "scan.ply").size(), *result.figures.points);
}

TEST(ScanOutput, AFailurePartWayLeavesNoFileAndTheOldOnesAsTheyWere) {
  Acquired& scan = mainScan();
  TempDir out;
  out.write("cloud.ply", "an earlier cloud");
  out.write("blocked", "a file where a directory is needed");
  ScanCalibrations calibrations;
  calibrations.main = everywhere({160, 128});
  ScanOutputOptions options;
  options.depth = "blocked/depth.tiff";  // written after the cloud, and cannot be
  try {
    writeScanOutput(scan.phase, calibrations, options, out.path());
    ADD_FAILURE() << "no error";
  } catch (const std::system_error& e) {
    // Named as asked, not by its temporary name.
    EXPECT_NE(std::string(e.what()).find((out.path() / "blocked/depth.tiff").string()),
              std::string::npos)
        << e.what();
    EXPECT_EQ(std::string(e.what()).find(".partial"), std::string::npos) << e.what();
  }
  EXPECT_EQ(entries(out.path()), (std::set<std::string>{"cloud.ply", "blocked"}));
  EXPECT_EQ(fileText(out.path() / "cloud.ply"), "an earlier cloud");
}

TEST(ScanOutput, ACalibrationForAnotherImageSizeIsUnusable) {
  TempDir calib;
  install(everywhere({80, 64}), calib.path() / "main.qcal");
  const CalibrationDir installed(calib.path());
  try {
    installed.calibration("main", {160, 128});
    FAIL() << "no UnusableCalibration";
  } catch (const UnusableCalibration& e) {
    EXPECT_EQ(e.camera(), "main");
    EXPECT_NE(std::string(e.what()).find("main.qcal"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("install it again"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(installed.calibration("cam90", {160, 128}));  // none installed
  EXPECT_FALSE(installed.head());
}

// A 360° scan of main and cam90 with both calibrated (cam90 on the high phase).
struct RingOutputs {
  TempDir calib, out;
  ScanCalibrations calibrations;
  ScanOutputOptions options;
  RingOutputs() {
    calibrations.main = everywhere({160, 128});
    install(everywhere({160, 128}, PhaseSource::High), calib.path() / "cam90.qcal");
    calibrations.installed = CalibrationDir(calib.path());
    options.ring_cameras = {"main", "cam90"};
  }
  ScanResult write() {
    return writeScanOutput(ringScan().phase, calibrations, options, out.path());
  }
};

TEST(ScanOutput, ARingScanWithoutHeadJsonHasEveryCamerasCloudAndMainsAloneMerged) {
  RingOutputs ring;
  const algo::PhaseMaps main = ringScan().phase.finalize("main");
  const algo::PhaseMaps cam90 = ringScan().phase.finalize("cam90");
  const ScanResult result = ring.write();
  const std::vector<std::string> files = {"cloud.ply",       "depth.tiff", "texture.png",
                                          "phase.png",       "depth.png",  "clouds/main.ply",
                                          "clouds/cam90.ply"};
  EXPECT_EQ(result.files, files);
  std::set<std::string> expected(files.begin(), files.end());
  expected.insert("clouds");
  EXPECT_EQ(entries(ring.out.path()), expected);
  ASSERT_TRUE(result.figures.ring);
  const RingOutput& r = *result.figures.ring;
  ASSERT_EQ(r.cameras.size(), 2u);
  EXPECT_EQ(r.cameras[0].points, finitePixels(main.fused));
  EXPECT_EQ(r.cameras[0].phase, PhaseSource::Fused);
  EXPECT_EQ(r.cameras[1].camera, "cam90");
  EXPECT_TRUE(r.cameras[1].calibrated);
  EXPECT_EQ(r.cameras[1].phase, PhaseSource::High);  // its calibration's own
  EXPECT_EQ(r.cameras[1].points, finitePixels(cam90.absolute));
  EXPECT_EQ(r.cameras[1].phase_valid_fraction, cam90.valid_fraction);
  EXPECT_EQ(r.cameras[1].file, "clouds/cam90.ply");
  EXPECT_EQ(formats::readPly(ring.out.path() / "clouds/cam90.ply").size(), r.cameras[1].points);
  EXPECT_EQ(r.cloud, MergedCloud::kMain);
  EXPECT_NE(r.cloud_note.find("no head extrinsics installed"), std::string::npos) << r.cloud_note;
  EXPECT_NE(r.cloud_note.find("cam90"), std::string::npos) << r.cloud_note;
  EXPECT_EQ(result.figures.points, r.cameras[0].points);
  const formats::PointCloud merged = formats::readPly(ring.out.path() / "cloud.ply");
  EXPECT_EQ(merged.size(), r.cameras[0].points);
  EXPECT_EQ(formats::cameraNamesOf(merged), std::vector<std::string>{"main"});
}

TEST(ScanOutput, ARingScanWithHeadJsonMergesEveryCalibratedCamera) {
  RingOutputs ring;
  ring.calib.write("head.json", R"({"format": "cylscan-head-1", "frame": "main",
    "method": "turntable", "rms_mm": 0.02, "cameras": {
    "main": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]},
    "cam90": {"R": [[0,0,1],[0,1,0],[-1,0,0]], "T": [120,0,120]}}})");
  const ScanResult result = ring.write();
  ASSERT_TRUE(result.figures.ring);
  const RingOutput& r = *result.figures.ring;
  EXPECT_EQ(r.cloud, MergedCloud::kMerged);
  EXPECT_EQ(r.cloud_note, "");
  ASSERT_TRUE(result.figures.points);
  EXPECT_EQ(*result.figures.points, r.cameras[0].points + r.cameras[1].points);
  const formats::PointCloud merged = formats::readPly(ring.out.path() / "cloud.ply");
  EXPECT_EQ(merged.size(), *result.figures.points);
  EXPECT_EQ(formats::cameraNamesOf(merged), (std::vector<std::string>{"main", "cam90"}));
}

TEST(ScanOutput, AnUnusableCalibrationOfARingCameraLeavesNothing) {
  RingOutputs ring;
  ring.calib.write("cam90.qcal", "not a calibration any more");
  try {
    ring.write();
    FAIL() << "no UnusableCalibration";
  } catch (const UnusableCalibration& e) {
    EXPECT_EQ(e.camera(), "cam90");
    EXPECT_NE(std::string(e.what()).find("cam90.qcal"), std::string::npos) << e.what();
  }
  // Main's files were written before cam90's turn: none is left, nor clouds/.
  EXPECT_EQ(entries(ring.out.path()), std::set<std::string>{});
}

TEST(ScanOutput, ARingScanWithNoCameraCalibratedHasNoCloud) {
  TempDir out;
  ScanOutputOptions options;
  options.ring_cameras = {"main", "cam90"};
  const ScanResult result = writeScanOutput(ringScan().phase, {}, options, out.path());
  EXPECT_EQ(result.files, (std::vector<std::string>{"texture.png", "phase.png"}));
  EXPECT_EQ(entries(out.path()), (std::set<std::string>{"texture.png", "phase.png"}));
  ASSERT_TRUE(result.figures.ring);
  EXPECT_EQ(result.figures.ring->cloud, MergedCloud::kNone);
  EXPECT_NE(result.figures.ring->cloud_note.find("no camera is calibrated"), std::string::npos);
  EXPECT_EQ(result.figures.points, std::size_t{0});
  for (const CameraOutput& c : result.figures.ring->cameras) {
    EXPECT_FALSE(c.calibrated) << c.camera;
    EXPECT_EQ(c.points, 0u) << c.camera;
  }
}

}  // namespace
}  // namespace cylscan::firmware
