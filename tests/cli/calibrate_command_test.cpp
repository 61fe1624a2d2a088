// SPDX-License-Identifier: Apache-2.0
// `cylscan calibrate` and `cylscan calibrate-stereo`: the bad-input and
// failure paths (the working paths run end to end in end_to_end_test.cpp).
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli_support.hpp"
#include "formats/checkerboard_set.hpp"
#include "formats/images.hpp"
#include "formats/stereo_calibration.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;

formats::StereoCalibration stereoFor(cv::Size size) {
  formats::StereoCalibration c;
  c.image_width = size.width;
  c.image_height = size.height;
  c.camera_matrix_main = cv::Matx33d(300, 0, size.width / 2.0, 0, 300, size.height / 2.0, 0, 0, 1);
  c.camera_matrix_aux = c.camera_matrix_main;
  c.R = cv::Matx33d::eye();
  c.T = cv::Vec3d(-100, 0, 0);
  return c;
}

class CalibrateCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    writeSyntheticBundle(tmp_.path() / "stereo_pose", size_, 4, {"main", "aux"});
    writeSyntheticBundle(tmp_.path() / "main_only", size_, 4);
    formats::writeStereoCalibration(path("stereo.yaml"), stereoFor(size_));
  }
  fs::path path(const std::string& name) const { return tmp_.path() / name; }
  // `count` arguments naming bundles: the stereo pose, with `odd` at position `at`.
  std::string bundles(int count, const std::string& odd = "", int at = -1) const {
    std::string args;
    for (int i = 0; i < count; ++i) {
      args += " " + (i == at ? odd : path("stereo_pose").string());
    }
    return args;
  }
  std::string command(const std::string& stereo = "stereo.yaml") const {
    return "calibrate --stereo " + path(stereo).string() + " --out " + path("calib.qcal").string();
  }

  TempDir tmp_;
  cv::Size size_{48, 32};
};

TEST_F(CalibrateCommand, TooFewPosesIsBadInput) {
  const auto run = runTool(command() + bundles(5));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("at least 6"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(path("calib.qcal")));
}

TEST_F(CalibrateCommand, BundleWithoutAuxIsBadInputNamingTheBundle) {
  const auto run = runTool(command() + bundles(7, path("main_only").string(), 4));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("main_only"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("'aux'"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(path("calib.qcal")));
}

TEST_F(CalibrateCommand, MissingBundleIsBadInputNamingIt) {
  const auto run = runTool(command() + bundles(6, path("nowhere").string(), 2));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("nowhere"), std::string::npos) << run.output;
}

TEST_F(CalibrateCommand, StereoGarbageOrMissingIsBadInputNamingTheFile) {
  std::ofstream(path("garbage.yaml")) << "this: is: not [a stereo calibration\n";
  auto run = runTool(command("garbage.yaml") + bundles(6));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("garbage.yaml"), std::string::npos) << run.output;

  run = runTool(command("absent.yaml") + bundles(6));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("absent.yaml"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(path("calib.qcal")));
}

TEST_F(CalibrateCommand, StereoForAnotherImageSizeIsBadInputNamingIt) {
  formats::writeStereoCalibration(path("big.yaml"), stereoFor({640, 480}));
  const auto run = runTool(command("big.yaml") + bundles(6));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("big.yaml"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("48x32"), std::string::npos) << run.output;
}

TEST_F(CalibrateCommand, BadPhaseOptionIsAUsageError) {
  EXPECT_EQ(runTool(command() + " --phase low" + bundles(6)).exit_code, 2);
}

// A checkerboard set whose images show no board at all.
void writeBlankBoardSet(const fs::path& dir, int pairs) {
  formats::writeCheckerboardInfo(dir, {9, 6, 12.0});
  fs::create_directories(dir / "main");
  fs::create_directories(dir / "aux");
  const cv::Mat grey(64, 80, CV_8U, cv::Scalar(128));
  for (int i = 0; i < pairs; ++i) {
    const std::string name = (i < 10 ? "0" : "") + std::to_string(i) + ".png";
    formats::writePng(dir / "main" / name, grey);
    formats::writePng(dir / "aux" / name, grey);
  }
}

// A board found in no image at all is most often a checkerboard.json that
// counts squares: bad input, in one short line that names the file.
TEST(CalibrateStereoCommand, ABoardFoundNowhereIsBadInputNamingCheckerboardJson) {
  TempDir tmp;
  writeBlankBoardSet(tmp.path() / "board", 7);
  const fs::path out = tmp.path() / "stereo.yaml";
  const auto run = runTool("calibrate-stereo --board " + (tmp.path() / "board").string() +
                           " --out " + out.string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("checkerboard.json"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("9 x 6 inner corners"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("none of the 7 pairs"), std::string::npos) << run.output;
  EXPECT_LT(run.output.size(), 400u) << run.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(CalibrateStereoCommand, BoardFileProblemsAreBadInput) {
  TempDir tmp;
  const fs::path out = tmp.path() / "stereo.yaml";
  auto run = runTool("calibrate-stereo --board " + (tmp.path() / "nowhere").string() + " --out " +
                     out.string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("nowhere"), std::string::npos) << run.output;

  writeBlankBoardSet(tmp.path() / "board", 6);
  std::ofstream(tmp.path() / "board" / "checkerboard.json") << "{\"cols\": 9, \"rows\": ";
  run = runTool("calibrate-stereo --board " + (tmp.path() / "board").string() + " --out " +
                out.string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("checkerboard.json"), std::string::npos) << run.output;

  writeBlankBoardSet(tmp.path() / "board2", 6);
  std::ofstream(tmp.path() / "board2" / "aux" / "03.png", std::ios::trunc) << "not a png";
  run = runTool("calibrate-stereo --board " + (tmp.path() / "board2").string() + " --out " +
                out.string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("03.png"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(CalibrateStereoCommand, PairsOfDifferentSizesAreBadInput) {
  TempDir tmp;
  writeBlankBoardSet(tmp.path() / "board", 6);
  const cv::Mat other(48, 80, CV_8U, cv::Scalar(128));
  for (int i = 0; i < 6; ++i) {
    formats::writePng(tmp.path() / "board" / "aux" / ("0" + std::to_string(i) + ".png"), other);
  }
  const auto run = runTool("calibrate-stereo --board " + (tmp.path() / "board").string() +
                           " --out " + (tmp.path() / "stereo.yaml").string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("aux"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace cylscan::test
