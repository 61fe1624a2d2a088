// SPDX-License-Identifier: Apache-2.0
// OneSetPhase: the wrapped phase of one fringe set alone equals the phase
// engine's map of that set, on both paths, and flags what one set can tell.
#include "algo/one_set_phase.hpp"

#include <gtest/gtest.h>

#include "tests/algo/synthetic_fringes.hpp"

namespace cylscan::algo {
namespace {

using testing::deviceHigh;
using testing::deviceLow;
using testing::FringeRenderer;
using testing::Scene;
using testing::stepGeometry;

cv::Size smallSize() {
  return {96, 64};
}

PhaseOptions optionsOf(bool fixed, int bits) {
  PhaseOptions o;
  o.bit_depth = bits;
  o.fixed_point = fixed;
  return o;
}

OneSetMaps runOneSet(const Scene& scene, FringeSet set, const FringeSetGeometry& g,
                     const PhaseOptions& options) {
  OneSetPhase engine(scene.absolute_high.size(), set, g, options);
  FringeRenderer renderer(scene, options.bit_depth, 0.5, 7);
  for (int k = 0; k < static_cast<int>(g.stage_deg.size()); ++k)
    engine.fold(k, renderer.render(set, g, k));
  return engine.finalize();
}

double maxDifference(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(a, b, cv::NORM_INF);
}

TEST(OneSetPhase, EqualsTheEnginesMapsOfThatSet) {
  const Scene scene = testing::rampScene(smallSize(), 110, 80);
  for (const bool fixed : {true, false}) {
    for (const int bits : {8, 12}) {
      SCOPED_TRACE((fixed ? "fixed point, " : "reference, ") + std::to_string(bits) + " bit");
      const PhaseOptions options = optionsOf(fixed, bits);
      const double scale = 1 << (bits - 8);
      Scene scaled = scene;
      scaled.background = cv::Mat(scene.background * scale);  // new data: scene stays as it is
      scaled.modulation = cv::Mat(scene.modulation * scale);
      // The same noise seed renders the same frames: the engine folds the high
      // set first, as runOneSet does, so each set's frames match.
      const PhaseMaps both = testing::runScan(scaled, deviceHigh(), deviceLow(), options, 0.5);
      const OneSetMaps high = runOneSet(scaled, FringeSet::High, deviceHigh(), options);
      // Exact: the same weights, fold and atan2 (the C, S scale of a set depends
      // on that set alone), so not even rounding differs.
      EXPECT_EQ(maxDifference(high.wrapped, both.wrapped_high), 0.0);
      EXPECT_EQ(maxDifference(high.modulation, both.modulation_high), 0.0);
      // The texture is this set's A alone (the engine's is the mean of both
      // sets'): within noise of the true A. Per pixel its standard deviation is
      // about sqrt(0.5² + 1/12)/sqrt(25) = 0.12 counts (noise and rounding over
      // 25 frames), so 0.8 counts is about 7σ.
      cv::Mat error;
      cv::absdiff(high.texture, 110.0 * scale, error);
      EXPECT_LT(cv::norm(error, cv::NORM_INF), 0.8);
      EXPECT_GT(high.valid_fraction, 0.99);
    }
  }
}

TEST(OneSetPhase, TheLowSetAloneEqualsTheEnginesLowMap) {
  const Scene scene = testing::rampScene(smallSize(), 110, 80);
  for (const bool fixed : {true, false}) {
    SCOPED_TRACE(fixed ? "fixed point" : "reference");
    PhaseEngine engine(smallSize(), deviceHigh(), deviceLow(), optionsOf(fixed, 8));
    OneSetPhase low(smallSize(), FringeSet::Low, deviceLow(), optionsOf(fixed, 8));
    FringeRenderer renderer(scene, 8, 0.5, 11);
    const FringeSetGeometry high_g = deviceHigh(), low_g = deviceLow();
    for (int k = 0; k < static_cast<int>(low_g.stage_deg.size()); ++k) {
      const cv::Mat frame = renderer.render(FringeSet::Low, low_g, k);
      engine.fold(FringeSet::Low, k, frame);
      low.fold(k, frame);
    }
    for (int k = 0; k < static_cast<int>(high_g.stage_deg.size()); ++k)
      engine.fold(FringeSet::High, k, renderer.render(FringeSet::High, high_g, k));
    const PhaseMaps both = engine.finalize();
    const OneSetMaps alone = low.finalize();
    EXPECT_EQ(maxDifference(alone.wrapped, both.wrapped_low), 0.0);
    EXPECT_EQ(maxDifference(alone.modulation, both.modulation_low), 0.0);
  }
}

TEST(OneSetPhase, FlagsLowModulationAndSaturationOnly) {
  // Columns [0,32) dark (B = 2), [32,64) fine, [64,96) saturated (A + B = 300).
  Scene scene = testing::rampScene(smallSize(), 110, 80);
  scene.modulation.colRange(0, 32).setTo(2.0);
  scene.background.colRange(64, 96).setTo(200.0);
  scene.modulation.colRange(64, 96).setTo(100.0);
  for (const bool fixed : {true, false}) {
    SCOPED_TRACE(fixed ? "fixed point" : "reference");
    const OneSetMaps maps = runOneSet(scene, FringeSet::High, deviceHigh(), optionsOf(fixed, 8));
    for (int y = 0; y < smallSize().height; ++y) {
      for (int x = 0; x < smallSize().width; ++x) {
        const std::uint8_t flags = maps.invalid.at<std::uint8_t>(y, x);
        const std::uint8_t expected = x < 32 ? kLowModulation : x < 64 ? kValid : kSaturated;
        ASSERT_EQ(flags & ~kLowModulation & 0xFF, expected & ~kLowModulation & 0xFF)
            << x << "," << y;
        if (x < 32) {
          ASSERT_TRUE(flags & kLowModulation) << x << "," << y;
        }
        if (x >= 32 && x < 64) {
          ASSERT_EQ(flags, kValid) << x << "," << y;
        }
      }
    }
    EXPECT_NEAR(maps.valid_fraction, 1.0 / 3.0, 1e-9);
  }
}

TEST(OneSetPhase, RejectsBadShiftsFramesAndFoldOrder) {
  EXPECT_THROW(OneSetPhase(smallSize(), FringeSet::High, stepGeometry(5.0, 4, 0.0, 0.0)),
               ShiftSolveError);
  EXPECT_THROW(OneSetPhase(cv::Size(0, 4), FringeSet::High, deviceHigh()), std::invalid_argument);
  OneSetPhase engine(smallSize(), FringeSet::High, stepGeometry(5.0, 3));
  const cv::Mat frame(smallSize(), CV_8UC1, cv::Scalar(100));
  EXPECT_THROW(engine.fold(3, frame), std::out_of_range);
  EXPECT_THROW(engine.fold(0, cv::Mat(4, 4, CV_8UC1)), std::invalid_argument);
  EXPECT_THROW(engine.fold(0, cv::Mat(smallSize(), CV_16UC1)), std::invalid_argument);
  engine.fold(0, frame);
  EXPECT_THROW(engine.fold(0, frame), std::logic_error);
  EXPECT_THROW((void)engine.finalize(), std::logic_error);
  engine.fold(1, frame);
  engine.fold(2, frame);
  EXPECT_NO_THROW((void)engine.finalize());
}

}  // namespace
}  // namespace cylscan::algo
