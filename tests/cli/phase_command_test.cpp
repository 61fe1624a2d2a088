// SPDX-License-Identifier: Apache-2.0
// `cylscan phase` run as a user runs it: outputs, JSON summary, exit codes.
#include <cmath>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli_support.hpp"
#include "formats/images.hpp"

namespace cylscan::test {
namespace {

namespace fs = std::filesystem;

TEST(PhaseCommand, WritesTheSpecMapsAndRecoversTheAbsolutePhase) {
  TempDir tmp;
  const auto truth = writeSyntheticBundle(tmp.path() / "bundle", {96, 64});
  const auto run = runTool("phase --json --out " + (tmp.path() / "out").string() + " " +
                           (tmp.path() / "bundle").string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* name : {"wrapped_high.tiff", "wrapped_low.tiff", "absolute.tiff",
                           "modulation_high.tiff", "texture.png"}) {
    EXPECT_TRUE(fs::exists(tmp.path() / "out" / name)) << name;
  }
  const auto summary = nlohmann::json::parse(run.output);
  EXPECT_EQ(summary.at("camera"), "main");
  EXPECT_GT(summary.at("valid_fraction").get<double>(), 0.99);
  EXPECT_NEAR(summary.at("mean_modulation").get<double>(), 90.0, 2.0);
  EXPECT_TRUE(summary.at("timings_ms").contains("fold"));

  const cv::Mat absolute = formats::readFloatTiff(tmp.path() / "out" / "absolute.tiff");
  ASSERT_EQ(absolute.size(), truth.absolute.size());
  int wrong_order = 0;
  double worst = 0;
  for (int v = 0; v < absolute.rows; ++v) {
    for (int u = 0; u < absolute.cols; ++u) {
      const double measured = absolute.at<float>(v, u);
      ASSERT_TRUE(std::isfinite(measured)) << "pixel " << u << "," << v;
      const double error = std::abs(measured - truth.absolute.at<double>(v, u));
      if (error > 3.0) ++wrong_order;  // a fringe-order error is 2π away
      worst = std::max(worst, error);
    }
  }
  EXPECT_EQ(wrong_order, 0);
  EXPECT_LT(worst, 0.02);  // 8-bit quantisation at B = 90 counts, N = 12

  const cv::Mat wrapped = formats::readFloatTiff(tmp.path() / "out" / "wrapped_high.tiff");
  double lo = 0, hi = 0;
  cv::minMaxLoc(wrapped, &lo, &hi);
  EXPECT_GE(lo, 0.0);
  EXPECT_LT(hi, 6.2832);
  const cv::Mat texture =
      cv::imread((tmp.path() / "out" / "texture.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(texture.type(), CV_8UC1);
  EXPECT_NEAR(cv::mean(texture)[0], 120.0, 1.5);
}

TEST(PhaseCommand, ReferencePathAgreesWithTheFixedPointPath) {
  TempDir tmp;
  writeSyntheticBundle(tmp.path() / "bundle", {64, 48});
  const std::string bundle = (tmp.path() / "bundle").string();
  ASSERT_EQ(runTool("phase --out " + (tmp.path() / "fixed").string() + " " + bundle).exit_code, 0);
  ASSERT_EQ(
      runTool("phase --reference --out " + (tmp.path() / "ref").string() + " " + bundle).exit_code,
      0);
  const cv::Mat fixed = formats::readFloatTiff(tmp.path() / "fixed" / "absolute.tiff");
  const cv::Mat ref = formats::readFloatTiff(tmp.path() / "ref" / "absolute.tiff");
  cv::Mat diff;
  cv::absdiff(fixed, ref, diff);
  double worst = 0;
  cv::minMaxLoc(diff, nullptr, &worst);
  EXPECT_LT(worst, 4e-3);
}

TEST(PhaseCommand, MissingBundleIsBadInputNamingTheFile) {
  TempDir tmp;
  const auto run = runTool("phase --out " + (tmp.path() / "out").string() + " " +
                           (tmp.path() / "nowhere").string());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("capture.json"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(tmp.path() / "out"));
}

TEST(PhaseCommand, UnknownCameraIsBadInput) {
  TempDir tmp;
  writeSyntheticBundle(tmp.path() / "bundle", {32, 24}, 4);
  const auto run = runTool("phase --camera side --out " + (tmp.path() / "out").string() + " " +
                           (tmp.path() / "bundle").string());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("side"), std::string::npos) << run.output;
}

TEST(PhaseCommand, SingularShiftsAreBadInputNamingCaptureJson) {
  TempDir tmp;
  writeSyntheticBundle(tmp.path() / "bundle", {32, 24}, 4);
  // Every frame of the low set at the same angle: the least squares is singular.
  const fs::path json_path = tmp.path() / "bundle" / "capture.json";
  nlohmann::json capture = nlohmann::json::parse(std::ifstream(json_path));
  for (auto& angle : capture["sets"]["low"]["stage_deg"])
    angle = 7.0;
  std::ofstream(json_path) << capture.dump();
  const auto run = runTool("phase --out " + (tmp.path() / "out").string() + " " +
                           (tmp.path() / "bundle").string());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("capture.json"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("low"), std::string::npos) << run.output;
}

TEST(PhaseCommand, CorruptFrameIsBadInputNamingTheFrame) {
  TempDir tmp;
  writeSyntheticBundle(tmp.path() / "bundle", {32, 24}, 4);
  const fs::path frame = tmp.path() / "bundle" / "main" / "low" / "02.png";
  std::ofstream(frame, std::ios::binary | std::ios::trunc) << "not a png at all";
  const auto run = runTool("phase --out " + (tmp.path() / "out").string() + " " +
                           (tmp.path() / "bundle").string());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("02.png"), std::string::npos) << run.output;
}

TEST(PhaseCommand, UsageErrorsExitWithTwo) {
  EXPECT_EQ(runTool("phase").exit_code, 2);
  EXPECT_EQ(runTool("no-such-command").exit_code, 2);
}

}  // namespace
}  // namespace cylscan::test
