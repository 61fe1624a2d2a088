// SPDX-License-Identifier: Apache-2.0
// The virtual cameras behind drivers::Camera: triggers, exposure at the stage
// angle of the moment, sequence numbers, software trigger, timeouts, the
// fault-injection hooks, and the exposure and gain controls with their ranges.
#include <gtest/gtest.h>

#include <string>
#include <utility>

#include "sim_test_support.hpp"

namespace cylscan::sim {
namespace {

using namespace std::chrono_literals;
using test::LineDriver;

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

class CameraTest : public ::testing::Test {
 protected:
  explicit CameraTest(HeadConfig head_config = test::smallHead())
      : head(std::move(head_config), test::planeScene()), lines(head), cam(head.camera("main")) {
    drivers::CameraConfig config;
    config.trigger = drivers::TriggerMode::GpioPulse;
    cam.configure(config);
    cam.start();
  }
  drivers::Frame shoot() {
    lines.pulseTrigger();
    auto f = cam.waitFrame(5s);
    EXPECT_TRUE(f);
    return f ? *f : drivers::Frame{};
  }
  // One frame with the camera configured so (12 bits: fine counts).
  drivers::Frame shootWith(double exposure_us, double gain) {
    cam.stop();
    drivers::CameraConfig config;
    config.bit_depth = 12;
    config.exposure_us = exposure_us;
    config.gain = gain;
    cam.configure(config);
    cam.start();
    return shoot();
  }
  VirtualHead head;
  LineDriver lines;
  drivers::Camera& cam;
};

TEST_F(CameraTest, TriggerGivesAFrameWithSequenceAndTimestamp) {
  head.clock().sleepUntil(100ms);
  const auto t = head.clock().now();
  const drivers::Frame f = shoot();
  EXPECT_EQ(f.sequence, 0u);
  EXPECT_EQ(f.timestamp, t + 20us);  // the trigger latency
  EXPECT_EQ(f.image.size(), cv::Size(200, 160));
  EXPECT_EQ(f.image.type(), CV_8UC1);
  EXPECT_GE(head.clock().now(), f.timestamp + 10ms + 8ms);  // exposure + readout
  EXPECT_EQ(shoot().sequence, 1u);
}

TEST_F(CameraTest, TheFrameShowsTheStageAngleOfTheTrigger) {
  const drivers::Frame at0 = shoot();
  lines.move(50);  // 0.2°: a fifth of... a 25th of a period
  const drivers::Frame at50 = shoot();
  EXPECT_FALSE(same(at0.image, at50.image));
  lines.move(-50);
  // Trigger at the first angle, move once the exposure is over, then read.
  lines.pulseTrigger();
  head.clock().sleepUntil(head.clock().now() + 11ms);
  lines.move(50);
  const auto late = cam.waitFrame(1s);
  ASSERT_TRUE(late);
  EXPECT_TRUE(same(late->image, at0.image));
}

TEST_F(CameraTest, LightOffLeavesOnlyAmbient) {
  const drivers::Frame lit = shoot();
  lines.light->set(false);
  const drivers::Frame dark = shoot();
  double lo = 0, hi = 0;
  cv::minMaxLoc(dark.image, &lo, &hi);
  EXPECT_LE(hi - lo, 1.0);  // uniform plane, no fringes
  EXPECT_GT(cv::mean(lit.image)[0], 5 * cv::mean(dark.image)[0]);
}

TEST_F(CameraTest, TimeoutAdvancesVirtualTime) {
  const auto t = head.clock().now();
  EXPECT_FALSE(cam.waitFrame(50ms));
  EXPECT_EQ(head.clock().now() - t, 50ms);
}

TEST_F(CameraTest, SoftwareTrigger) {
  EXPECT_THROW(cam.requestFrame(), drivers::CameraError);
  cam.stop();
  drivers::CameraConfig config;
  config.trigger = drivers::TriggerMode::Software;
  config.bit_depth = 12;
  cam.configure(config);
  cam.start();
  lines.pulseTrigger();  // ignored in software mode
  EXPECT_FALSE(cam.waitFrame(30ms));
  cam.requestFrame();
  const auto f = cam.waitFrame(1s);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->image.type(), CV_16UC1);
  double hi = 0;
  cv::minMaxLoc(f->image, nullptr, &hi);
  EXPECT_GT(hi, 1000);  // 12-bit counts, unscaled
  EXPECT_LE(hi, 4095);
}

TEST_F(CameraTest, FreeRunningStreams) {
  cam.stop();
  drivers::CameraConfig config;
  config.trigger = drivers::TriggerMode::FreeRunning;
  cam.configure(config);
  cam.start();
  const auto a = cam.waitFrame(1s), b = cam.waitFrame(1s);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(b->sequence, a->sequence + 1);
  EXPECT_NEAR(static_cast<double>((b->timestamp - a->timestamp).count()), 1e9 / 30, 1e3);
}

TEST_F(CameraTest, AFreeRunningStreamNumbersItsFramesOnItsOwnClock) {
  cam.stop();
  drivers::CameraConfig config;
  config.trigger = drivers::TriggerMode::FreeRunning;
  cam.configure(config);
  cam.start();
  const auto a = cam.waitFrame(1s);
  ASSERT_TRUE(a);
  // Ten periods nobody reads: those frames are never delivered, and the
  // sequence says how many.
  head.clock().sleepUntil(head.clock().now() + 10 * 33'333'333ns);
  const auto b = cam.waitFrame(1s);
  ASSERT_TRUE(b);
  EXPECT_GE(b->sequence, a->sequence + 10);
  EXPECT_LE(b->sequence, a->sequence + 11);
  EXPECT_NEAR(static_cast<double>((b->timestamp - a->timestamp).count()),
              static_cast<double>(b->sequence - a->sequence) * 1e9 / 30, 1e3);
}

TEST_F(CameraTest, ATriggeredContinuousStreamRepeatsTheLatestExposure) {
  cam.stop();
  drivers::CameraConfig config;
  config.trigger = drivers::TriggerMode::GpioPulse;
  config.stream = drivers::FrameStream::Continuous;
  cam.configure(config);
  cam.start();
  // Before any trigger the link carries black frames, one per period.
  const auto black = cam.waitFrame(1s);
  ASSERT_TRUE(black);
  EXPECT_EQ(cv::countNonZero(black->image), 0);
  const auto next = cam.waitFrame(1s);
  ASSERT_TRUE(next);
  EXPECT_EQ(next->sequence, black->sequence + 1);
  EXPECT_EQ(cv::countNonZero(next->image), 0) << "no trigger yet";

  const auto t = head.clock().now();
  lines.pulseTrigger();
  // The exposure is on the link from the first frame that starts after it
  // ended (trigger latency + exposure + readout: 18.02 ms) and stays there.
  std::optional<drivers::Frame> first;
  while (!first) {
    auto f = cam.waitFrame(1s);
    ASSERT_TRUE(f);
    if (cv::countNonZero(f->image) > 0) first = std::move(f);
  }
  EXPECT_GE(first->timestamp, t + 20us + 18ms);
  EXPECT_LT(first->timestamp, t + 20us + 18ms + 33'333'334ns);
  const auto again = cam.waitFrame(1s);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->sequence, first->sequence + 1);
  EXPECT_TRUE(same(again->image, first->image));

  // A new exposure at another angle replaces it.
  lines.move(50);
  lines.pulseTrigger();
  head.clock().sleepUntil(head.clock().now() + 60ms);
  const auto moved = cam.waitFrame(1s);
  ASSERT_TRUE(moved);
  EXPECT_FALSE(same(moved->image, first->image));
  EXPECT_GT(cv::countNonZero(moved->image), 0);
}

TEST_F(CameraTest, ConfigurationIsChecked) {
  cam.stop();
  drivers::CameraConfig config;
  config.width = 640;
  config.height = 480;
  EXPECT_THROW(cam.configure(config), drivers::CameraError);
  config = {};
  config.bit_depth = 9;
  EXPECT_THROW(cam.configure(config), drivers::CameraError);
  config = {};
  config.trigger = drivers::TriggerMode::Software;
  config.stream = drivers::FrameStream::Continuous;
  EXPECT_THROW(cam.configure(config), drivers::CameraError);
  cam.start();
  EXPECT_THROW(cam.configure({}), drivers::CameraError);
}

TEST_F(CameraTest, DroppedFrameLeavesASequenceGap) {
  head.dropFrames("main", 1);
  lines.pulseTrigger();
  head.clock().sleepUntil(head.clock().now() + 20ms);
  lines.pulseTrigger();
  const auto f = cam.waitFrame(1s);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->sequence, 1u);
  EXPECT_FALSE(cam.waitFrame(100ms));
}

TEST_F(CameraTest, DelayedFrameTimesOutThenArrives) {
  head.delayNextFrame("main", 200ms);
  lines.pulseTrigger();
  EXPECT_FALSE(cam.waitFrame(100ms));
  EXPECT_TRUE(cam.waitFrame(200ms));
}

TEST_F(CameraTest, CorruptedFrameDiffers) {
  const drivers::Frame good = shoot();
  head.corruptNextFrame("main");
  const drivers::Frame bad = shoot();
  EXPECT_FALSE(same(good.image, bad.image));
  EXPECT_TRUE(same(good.image.rowRange(0, 80), bad.image.rowRange(0, 80)));
}

TEST_F(CameraTest, TriggerDuringExposureIsMissed) {
  lines.pulseTrigger();
  head.clock().sleepUntil(head.clock().now() + 1ms);
  lines.pulseTrigger();
  EXPECT_TRUE(cam.waitFrame(1s));
  EXPECT_FALSE(cam.waitFrame(100ms));
  EXPECT_EQ(head.missedTriggers("main"), 1u);
}

TEST_F(CameraTest, ReportsTheConfiguredControlsAndTheSensorsRange) {
  // Configured with exposure_us = 0: the model's default exposure.
  drivers::CameraControls c = cam.controls();
  EXPECT_DOUBLE_EQ(c.exposure_us.value, 10000.0);
  EXPECT_DOUBLE_EQ(c.exposure_us.min, 20.0);
  EXPECT_DOUBLE_EQ(c.exposure_us.max, 200000.0);
  EXPECT_DOUBLE_EQ(c.gain.value, 1.0);
  EXPECT_DOUBLE_EQ(c.gain.min, 1.0);
  EXPECT_DOUBLE_EQ(c.gain.max, 16.0);
  cam.stop();
  drivers::CameraConfig config;
  config.exposure_us = 2500;
  config.gain = 2.5;
  cam.configure(config);
  c = cam.controls();
  EXPECT_DOUBLE_EQ(c.exposure_us.value, 2500.0);
  EXPECT_DOUBLE_EQ(c.gain.value, 2.5);
  EXPECT_DOUBLE_EQ(c.exposure_us.max, 200000.0);
  EXPECT_DOUBLE_EQ(c.gain.max, 16.0);
}

TEST(CameraControls, TheRangeIsTheCameraModels) {
  HeadConfig config = test::smallHead();
  CameraParams& aux = config.cameras.at(1);
  aux.exposure_min_us = 50;
  aux.exposure_max_us = 30000;
  aux.gain_min = 0.5;
  aux.gain_max = 4;
  VirtualHead head(config, test::planeScene());
  drivers::Camera& cam = head.camera("aux");
  cam.configure(drivers::CameraConfig{});
  const drivers::CameraControls c = cam.controls();
  EXPECT_DOUBLE_EQ(c.exposure_us.value, 10000.0);
  EXPECT_DOUBLE_EQ(c.exposure_us.min, 50.0);
  EXPECT_DOUBLE_EQ(c.exposure_us.max, 30000.0);
  EXPECT_DOUBLE_EQ(c.gain.min, 0.5);
  EXPECT_DOUBLE_EQ(c.gain.max, 4.0);
  // main keeps the defaults.
  head.camera("main").configure(drivers::CameraConfig{});
  EXPECT_DOUBLE_EQ(head.camera("main").controls().exposure_us.max, 200000.0);
}

TEST_F(CameraTest, TwiceTheExposureDoublesTheCounts) {
  const drivers::Frame short_frame = shootWith(2500, 1.0);
  const drivers::Frame long_frame = shootWith(5000, 1.0);
  ASSERT_EQ(long_frame.image.type(), CV_16UC1);
  // Where neither frame is clipped (at 0 or at the 12-bit full scale).
  const cv::Mat unclipped = (long_frame.image < 4095) & (short_frame.image > 0);
  ASSERT_GT(cv::countNonZero(unclipped), static_cast<int>(unclipped.total() * 9 / 10));
  const double short_mean = cv::mean(short_frame.image, unclipped)[0];
  const double long_mean = cv::mean(long_frame.image, unclipped)[0];
  EXPECT_GT(short_mean, 100.0);  // a signal well above the rounding
  // Noiseless head, linear response (gamma 1), the stage and light unchanged
  // and no LED warm-up: counts are proportional to the exposure, and only
  // their rounding to whole counts (under 0.5 of a mean of several hundred,
  // so 0.2 %) moves the ratio off 2.
  EXPECT_NEAR(long_mean / short_mean, 2.0, 0.01);
}

TEST_F(CameraTest, ValuesOutOfRangeAreClampedToIt) {
  // A plane dim enough (1/320 of the default's albedo) for the longest
  // exposure at the highest gain, 320 times the default's signal, not to clip.
  head.setScene(test::planeScene(580.0, 0.0025));
  const drivers::Frame too_long = shootWith(1e6, 100.0);
  EXPECT_DOUBLE_EQ(cam.controls().exposure_us.value, 200000.0);
  EXPECT_DOUBLE_EQ(cam.controls().gain.value, 16.0);
  const drivers::Frame at_max = shootWith(200000, 16.0);
  double lo = 0, hi = 0;
  cv::minMaxLoc(at_max.image, &lo, &hi);
  ASSERT_LT(hi, 4095.0);  // unclipped, so the frames below can differ
  EXPECT_TRUE(same(too_long.image, at_max.image));
  EXPECT_FALSE(same(shootWith(100000, 16.0).image, at_max.image));

  // The default plane: a few counts in the shortest exposure.
  head.setScene(test::planeScene());
  const drivers::Frame too_short = shootWith(5, 0.25);
  EXPECT_DOUBLE_EQ(cam.controls().exposure_us.value, 20.0);
  EXPECT_DOUBLE_EQ(cam.controls().gain.value, 1.0);
  EXPECT_TRUE(same(too_short.image, shootWith(20, 1.0).image));
  EXPECT_FALSE(same(too_short.image, shootWith(40, 1.0).image));

  // Values no sensor takes are refused, naming the key.
  cam.stop();
  drivers::CameraConfig bad;
  bad.gain = 0;
  try {
    cam.configure(bad);
    ADD_FAILURE() << "gain 0 accepted";
  } catch (const drivers::CameraError& e) {
    EXPECT_NE(std::string(e.what()).find("gain"), std::string::npos) << e.what();
  }
  bad.gain = 1;
  bad.exposure_us = -1;
  EXPECT_THROW(cam.configure(bad), drivers::CameraError);
}

// A sensor that exposes for seconds at a gain below unity (the head's
// default range is 20 µs to 200 ms, gain 1 to 16).
HeadConfig longExposureHead() {
  HeadConfig config = test::smallHead();
  config.cameras.front().exposure_max_us = 2e6;
  config.cameras.front().gain_min = 1.0 / 256;
  return config;
}

class LongExposureCameraTest : public CameraTest {
 protected:
  LongExposureCameraTest() : CameraTest(longExposureHead()) {}
};

TEST_F(LongExposureCameraTest, ExposureWhileMovingAveragesThePattern) {
  cam.stop();
  drivers::CameraConfig config;
  config.exposure_us = 1375000;  // 1.375 s while the stage turns 5°: one whole period
  config.gain = 1.0 / 137.5;     // the same counts as 10 ms at gain 1
  cam.configure(config);
  ASSERT_DOUBLE_EQ(cam.controls().exposure_us.value, 1375000.0);
  ASSERT_DOUBLE_EQ(cam.controls().gain.value, 1.0 / 137.5);
  cam.start();
  const drivers::Frame still = shoot();
  lines.pulseTrigger();
  lines.pulses(1250, 1100us);  // 909 steps/s (below the start rate) for 1.375 s
  const auto moving = cam.waitFrame(3s);
  ASSERT_TRUE(moving);
  double lo_s = 0, hi_s = 0, lo_m = 0, hi_m = 0;
  cv::minMaxLoc(still.image.row(80), &lo_s, &hi_s);
  cv::minMaxLoc(moving->image.row(80), &lo_m, &hi_m);
  EXPECT_LT(hi_m - lo_m, 0.2 * (hi_s - lo_s));                             // the fringes wash out
  EXPECT_NEAR((hi_m + lo_m) / 2, (hi_s + lo_s) / 2, 0.1 * (hi_s - lo_s));  // at the mean level
}

}  // namespace
}  // namespace cylscan::sim
