// SPDX-License-Identifier: Apache-2.0
// The fringe check's rules on maps made by hand: which pixels count as lit,
// the share saturated among them, the crest percentile, the advice and the
// picture. The daemon's test (tests/daemon_e2e/fringe_check_test.cpp) runs
// it on rendered frames.
#include "firmware/fringe_check.hpp"

#include <stdexcept>

#include <gtest/gtest.h>

namespace cylscan::firmware {
namespace {

constexpr int kWidth = 100;
constexpr int kHeight = 50;

// 8-bit maps: the first `lit_columns` columns carry fringes of background
// `a` and modulation `b`, the rest is dark (B = 1 count, under the 5.1 of
// the engine's default least modulation at 8 bits).
algo::PhaseMaps maps(float a, float b, int lit_columns = 90) {
  algo::PhaseMaps m;
  m.modulation_high = cv::Mat(kHeight, kWidth, CV_32FC1, cv::Scalar(1.0f));
  m.texture = cv::Mat(kHeight, kWidth, CV_32FC1, cv::Scalar(3.0f));
  m.invalid = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(algo::kLowModulation));
  m.modulation_high.colRange(0, lit_columns).setTo(b);
  m.texture.colRange(0, lit_columns).setTo(a);
  m.invalid.colRange(0, lit_columns).setTo(algo::kValid);
  return m;
}

algo::PhaseOptions eightBit() {
  algo::PhaseOptions o;
  o.bit_depth = 8;
  o.saturation_level = 255;
  o.min_modulation = 0.02 * 255;
  return o;
}

// Marks `n` lit pixels saturated (and so invalid), from the top left.
void saturate(algo::PhaseMaps& m, int n) {
  for (int i = 0; i < n; ++i)
    m.invalid.at<std::uint8_t>(i / 90, i % 90) = algo::kSaturated;
}

TEST(FringeCheck, AWellExposedWallIsRight) {
  const FringeQuality q = measureFringes(maps(120, 100), eightBit());
  EXPECT_DOUBLE_EQ(q.lit, 0.9);
  EXPECT_DOUBLE_EQ(q.usable, 0.9);
  EXPECT_DOUBLE_EQ(q.saturated, 0.0);
  EXPECT_FLOAT_EQ(q.modulation_median, 100);
  EXPECT_NEAR(q.peak, 220.0 / 255, 1e-6);
  EXPECT_EQ(q.advice, ExposureAdvice::kRight);
  ASSERT_EQ(q.picture.type(), CV_8UC3);
  ASSERT_EQ(q.picture.size(), cv::Size(kWidth, kHeight));
  // White is B = 127.5 counts, the most an unclipped 8-bit sinusoid has.
  EXPECT_EQ(q.picture.at<cv::Vec3b>(0, 0), cv::Vec3b(200, 200, 200));
  EXPECT_EQ(q.picture.at<cv::Vec3b>(0, 95), cv::Vec3b(2, 2, 2));
}

TEST(FringeCheck, DimFringesAskForMoreExposure) {
  // Crests at 55 counts of 255, a share of 0.22 < 0.45.
  const FringeQuality q = measureFringes(maps(30, 25), eightBit());
  EXPECT_NEAR(q.peak, 55.0 / 255, 1e-6);
  EXPECT_EQ(q.advice, ExposureAdvice::kRaise);
  // The dark columns do not count: the crests are the lit pixels'.
  const FringeQuality bright = measureFringes(maps(120, 100, 10), eightBit());
  EXPECT_EQ(bright.advice, ExposureAdvice::kRight);
  EXPECT_DOUBLE_EQ(bright.lit, 0.1);
}

TEST(FringeCheck, ClippedCrestsAskForLessExposureAndShowRed) {
  algo::PhaseMaps m = maps(120, 100);
  // 1 % of the 4500 lit pixels, ten times the share allowed.
  saturate(m, 45);
  const FringeQuality q = measureFringes(m, eightBit());
  EXPECT_EQ(q.advice, ExposureAdvice::kLower);
  EXPECT_DOUBLE_EQ(q.saturated, 45.0 / (kWidth * kHeight));
  EXPECT_DOUBLE_EQ(q.usable, (4500.0 - 45) / (kWidth * kHeight));
  EXPECT_EQ(q.picture.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 255));
  EXPECT_EQ(q.picture.at<cv::Vec3b>(0, 45), cv::Vec3b(200, 200, 200));
}

TEST(FringeCheck, AFewGlintsAreTolerated) {
  algo::PhaseMaps m = maps(120, 100);
  saturate(m, 4);  // 0.09 % of the lit pixels, under the 0.1 % allowed
  EXPECT_EQ(measureFringes(m, eightBit()).advice, ExposureAdvice::kRight);
  saturate(m, 5);  // 0.11 %
  EXPECT_EQ(measureFringes(m, eightBit()).advice, ExposureAdvice::kLower);
}

TEST(FringeCheck, DeeperCamerasScaleByTheirFullScale) {
  algo::PhaseOptions twelve = eightBit();
  twelve.bit_depth = 12;
  twelve.saturation_level = 4095;
  twelve.min_modulation = 0.02 * 4095;
  // The 8-bit wall's counts are dim for a 12-bit camera.
  EXPECT_EQ(measureFringes(maps(120, 100), twelve).advice, ExposureAdvice::kRaise);
  EXPECT_DOUBLE_EQ(measureFringes(maps(120, 100), twelve).lit, 0.9);
  EXPECT_EQ(measureFringes(maps(1920, 1600), twelve).advice, ExposureAdvice::kRight);
}

TEST(FringeCheck, RefusesMismatchedMapsAndUnresolvedOptions) {
  algo::PhaseMaps m = maps(120, 100);
  m.texture = cv::Mat(kHeight, kWidth - 1, CV_32FC1, cv::Scalar(0.0f));
  EXPECT_THROW(measureFringes(m, eightBit()), std::invalid_argument);
  EXPECT_THROW(measureFringes(algo::PhaseMaps{}, eightBit()), std::invalid_argument);
  algo::PhaseOptions unresolved;
  EXPECT_THROW(measureFringes(maps(120, 100), unresolved), std::invalid_argument);
  EXPECT_EQ(toString(ExposureAdvice::kRaise), "raise");
  EXPECT_EQ(toString(ExposureAdvice::kLower), "lower");
  EXPECT_EQ(toString(ExposureAdvice::kRight), "right");
}

}  // namespace
}  // namespace cylscan::firmware
