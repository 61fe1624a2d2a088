// SPDX-License-Identifier: Apache-2.0
// `cylscan phase` run as a user runs it: outputs, JSON summary, exit codes.
#include <cmath>
#include <fstream>
#include <string>

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

// A bundle with the high set only: the same high frames as a two-set bundle,
// whose wrapped_high.tiff the one-set run must reproduce on either path.
TEST(PhaseCommand, OneSetBundleGivesTheWrappedPhaseOfItsSetAndNoAbsolutePhase) {
  TempDir tmp;
  const fs::path two = tmp.path() / "two";
  const fs::path one = tmp.path() / "one";
  writeSyntheticBundle(two, {64, 48});
  writeSyntheticBundle(one, {64, 48});
  removeFringeSet(one, FringeSet::Low);
  for (const std::string path : {"", "--reference "}) {
    SCOPED_TRACE(path.empty() ? "fixed point" : "reference");
    const fs::path out_two = tmp.path() / ("out_two" + path.substr(0, 3));
    const fs::path out_one = tmp.path() / ("out_one" + path.substr(0, 3));
    ASSERT_EQ(runTool("phase " + path + "--out " + out_two.string() + " " + two.string()).exit_code,
              0);
    const auto run =
        runTool("phase --json " + path + "--out " + out_one.string() + " " + one.string());
    ASSERT_EQ(run.exit_code, 0) << run.output;

    for (const char* name :
         {"wrapped_high.tiff", "modulation_high.tiff", "texture.png", "invalid.png"}) {
      EXPECT_TRUE(fs::exists(out_one / name)) << name;
    }
    for (const char* name : {"wrapped_low.tiff", "absolute.tiff", "fused.tiff"}) {
      EXPECT_FALSE(fs::exists(out_one / name)) << name;
    }
    const auto summary = nlohmann::json::parse(run.output);
    EXPECT_EQ(summary.at("absolute"), false);
    EXPECT_EQ(summary.at("sets"), nlohmann::json::array({"high"}));
    EXPECT_NE(summary.at("note").get<std::string>().find("only the high set"), std::string::npos)
        << summary.dump();
    EXPECT_EQ(summary.at("frames"), nlohmann::json({{"high", 12}}));
    EXPECT_FALSE(summary.contains("order_residual"));
    EXPECT_GT(summary.at("valid_fraction").get<double>(), 0.99);

    // Tolerance 0: the one-set run folds the same frames with the same
    // least-squares weights (their C, S scale depends on the set alone) through
    // the same kernels and atan2 as the two-set run, so no rounding differs;
    // any difference means the code paths have drifted apart.
    const cv::Mat wrapped = formats::readFloatTiff(out_one / "wrapped_high.tiff");
    const cv::Mat wrapped_two = formats::readFloatTiff(out_two / "wrapped_high.tiff");
    ASSERT_EQ(wrapped.size(), wrapped_two.size());
    EXPECT_EQ(cv::norm(wrapped, wrapped_two, cv::NORM_INF), 0.0);
    const cv::Mat modulation = formats::readFloatTiff(out_one / "modulation_high.tiff");
    EXPECT_EQ(cv::norm(modulation, formats::readFloatTiff(out_two / "modulation_high.tiff"),
                       cv::NORM_INF),
              0.0);

    // No order is taken, so no pixel can be order-inconsistent.
    const cv::Mat invalid = cv::imread((out_one / "invalid.png").string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(invalid.type(), CV_8UC1);
    EXPECT_EQ(cv::countNonZero(invalid & 4), 0);
    const cv::Mat texture = cv::imread((out_one / "texture.png").string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(texture.type(), CV_8UC1);
    EXPECT_NEAR(cv::mean(texture)[0], 120.0, 1.5);  // A of the synthetic frames
  }

  const auto text = runTool("phase --out " + (tmp.path() / "text").string() + " " + one.string());
  ASSERT_EQ(text.exit_code, 0) << text.output;
  EXPECT_NE(text.output.find("no absolute phase"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("only the high set"), std::string::npos) << text.output;
}

TEST(PhaseCommand, TwoSetSummarySaysItHasTheAbsolutePhase) {
  TempDir tmp;
  writeSyntheticBundle(tmp.path() / "bundle", {32, 24}, 4);
  const auto run = runTool("phase --json --out " + (tmp.path() / "out").string() + " " +
                           (tmp.path() / "bundle").string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const auto summary = nlohmann::json::parse(run.output);
  EXPECT_EQ(summary.at("absolute"), true);
  EXPECT_EQ(summary.at("sets"), nlohmann::json::array({"high", "low"}));
}

TEST(PhaseCommand, BundleWithoutAnySetIsBadInputNamingCaptureJson) {
  TempDir tmp;
  const fs::path bundle = tmp.path() / "bundle";
  writeSyntheticBundle(bundle, {32, 24}, 4);
  removeFringeSet(bundle, FringeSet::Low);
  removeFringeSet(bundle, FringeSet::High);
  const auto run = runTool("phase --out " + (tmp.path() / "out").string() + " " + bundle.string());
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("capture.json"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("neither set"), std::string::npos) << run.output;
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
