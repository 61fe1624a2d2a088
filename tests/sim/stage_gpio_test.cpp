// SPDX-License-Identifier: Apache-2.0
// The rotation stage behind the GPIO backend: step counting, direction,
// enable, lost steps, the home switch and the fault line, driven with the
// virtual clock like firmware would.
#include <gtest/gtest.h>

#include "sim_test_support.hpp"

namespace cylscan::sim {
namespace {

using namespace std::chrono_literals;
using test::LineDriver;

class StageTest : public ::testing::Test {
 protected:
  StageTest() : head(test::smallHead(), test::planeScene()), lines(head) {}
  VirtualHead head;
  LineDriver lines;
};

TEST_F(StageTest, SlowStepsAreCountedExactlyAndDirReverses) {
  lines.pulses(1000, 2ms);  // 500 steps/s, below the start/stop rate
  EXPECT_EQ(head.stage().position(), 1000);
  EXPECT_EQ(head.stage().counters().pulses, 1000u);
  EXPECT_EQ(head.stage().counters().lost, 0u);
  EXPECT_NEAR(head.stage().angleDeg(), 4.0, 1e-12);  // 250 steps per degree
  lines.dir->set(false);
  lines.pulses(400, 2ms);
  EXPECT_EQ(head.stage().position(), 600);
  EXPECT_EQ(head.stage().counters().backward, 400u);
}

TEST_F(StageTest, NoMotionWhileDisabled) {
  lines.enable->set(false);
  lines.pulses(100, 2ms);
  EXPECT_EQ(head.stage().position(), 0);
  EXPECT_EQ(head.stage().counters().ignored, 100u);
  lines.enable->set(true);
  lines.pulses(10, 2ms);
  EXPECT_EQ(head.stage().position(), 10);
}

TEST_F(StageTest, TooFastLosesStepsAndRaisesTheFault) {
  auto fault = head.gpio().requestInput(LineDriver::spec("fault"));
  EXPECT_FALSE(fault->get());
  lines.pulses(500, 10us);  // 100 kHz = 400°/s: far beyond the pull-out speed
  EXPECT_GT(head.stage().counters().lost, 400u);
  EXPECT_LT(head.stage().position(), 500);
  EXPECT_TRUE(fault->get());
  const auto edge = fault->waitEdge(0ns);
  ASSERT_TRUE(edge);
  EXPECT_EQ(edge->edge, drivers::Edge::Rising);
  // Re-enabling the driver resynchronises the motor and clears the fault.
  lines.enable->set(false);
  lines.enable->set(true);
  EXPECT_FALSE(fault->get());
  const std::int64_t before = head.stage().position();
  lines.pulses(100, 2ms);
  EXPECT_EQ(head.stage().position(), before + 100);
}

TEST_F(StageTest, AnAccelerationRampIsFollowedAJumpIsNot) {
  // Ramp to 6000 steps/s (24°/s) at 60 % of the maximum acceleration.
  const double a = 0.6 * 120 * 250, v0 = 600;
  for (int i = 0; i < 3000; ++i) {
    const double v = std::min(std::sqrt(v0 * v0 + 2 * a * i), 6000.0);
    lines.pulses(1, std::chrono::nanoseconds(std::llround(1e9 / v)));
  }
  EXPECT_EQ(head.stage().counters().lost, 0u);
  EXPECT_EQ(head.stage().position(), 3000);
  // From the start rate straight to 5000 steps/s: stalls and stays stalled.
  head.clock().sleepUntil(head.clock().now() + 1s);
  lines.pulses(10, 1100us);
  lines.pulses(200, 200us);
  EXPECT_EQ(head.stage().counters().lost, 200u);
  EXPECT_EQ(head.stage().position(), 3010);
}

TEST_F(StageTest, ReversingAtSpeedLosesSteps) {
  for (int i = 0; i < 600; ++i) {
    const double v = std::min(std::sqrt(600.0 * 600 + 2 * 0.6 * 30000 * i), 4000.0);
    lines.pulses(1, std::chrono::nanoseconds(std::llround(1e9 / v)));
  }
  ASSERT_EQ(head.stage().counters().lost, 0u);
  lines.dir->set(false);
  lines.pulses(5, 250us);
  EXPECT_EQ(head.stage().counters().lost, 5u);
}

TEST_F(StageTest, InjectedStepLoss) {
  head.loseSteps(5);
  lines.pulses(20, 2ms);
  EXPECT_EQ(head.stage().position(), 15);
  EXPECT_EQ(head.stage().counters().lost, 5u);
}

TEST_F(StageTest, HomeSwitchEdgesAtTheTimeOfCrossing) {
  auto home = head.gpio().requestInput(LineDriver::spec("home"));
  EXPECT_TRUE(home->get());  // powered up at 0°, inside the ±0.1° window
  EXPECT_FALSE(home->waitEdge(0ns));
  // The window ends after 25 steps (0.1°): the 26th step leaves it.
  drivers::Nanoseconds t26{0};
  for (int i = 1; i <= 30; ++i) {
    lines.pulses(1, 2ms);
    if (i == 26) t26 = head.clock().now() - 2us;  // the rising edge of pulse 26
  }
  EXPECT_FALSE(home->get());
  auto edge = home->waitEdge(0ns);
  ASSERT_TRUE(edge);
  EXPECT_EQ(edge->edge, drivers::Edge::Falling);
  EXPECT_EQ(edge->timestamp, t26);
  EXPECT_FALSE(home->waitEdge(0ns));
  lines.dir->set(false);
  lines.pulses(10, 2ms);
  edge = home->waitEdge(0ns);
  ASSERT_TRUE(edge);
  EXPECT_EQ(edge->edge, drivers::Edge::Rising);
  EXPECT_TRUE(home->get());
  // Waiting with nothing to come lets virtual time pass.
  const auto before = head.clock().now();
  EXPECT_FALSE(home->waitEdge(30ms));
  EXPECT_EQ(head.clock().now() - before, 30ms);
}

TEST(SimGpio, UnknownAndMisusedLinesAreErrorsNamingTheLine) {
  VirtualHead head(test::smallHead(), test::planeScene());
  drivers::LineSpec spec;
  spec.name = "stepper";
  spec.role = "step";
  try {
    head.gpio().requestOutput(spec, false);
    FAIL() << "no error";
  } catch (const drivers::GpioError& e) {
    EXPECT_NE(std::string(e.what()).find("stepper"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("step"), std::string::npos);
  }
  EXPECT_THROW(head.gpio().requestOutput(LineDriver::spec("home"), false), drivers::GpioError);
  EXPECT_THROW(head.gpio().requestInput(LineDriver::spec("step")), drivers::GpioError);
  drivers::LineSpec by_offset;
  by_offset.chip = "gpiochip0";
  by_offset.offset = 17;
  EXPECT_THROW(head.gpio().requestOutput(by_offset, false), drivers::GpioError);
  auto step = head.gpio().requestOutput(LineDriver::spec("step"), false);
  EXPECT_THROW(head.gpio().requestOutput(LineDriver::spec("step"), false), drivers::GpioError);
  step.reset();
  EXPECT_NO_THROW(head.gpio().requestOutput(LineDriver::spec("step"), false));
}

TEST(SimGpio, PolarityIsHonoured) {
  // The default device's enable input is active-high: a request that says
  // active_low drives it inverted, so set(true) leaves the stage disabled.
  VirtualHead head(test::smallHead(), test::planeScene());
  drivers::LineSpec enable_spec = LineDriver::spec("enable");
  enable_spec.active_low = true;
  auto enable = head.gpio().requestOutput(enable_spec, true);
  auto step = head.gpio().requestOutput(LineDriver::spec("step"), false);
  auto& clock = head.clock();
  for (int i = 0; i < 5; ++i) {
    clock.sleepUntil(clock.now() + 2ms);
    step->set(true);
    clock.sleepUntil(clock.now() + 2us);
    step->set(false);
  }
  EXPECT_FALSE(head.stage().enabled());
  EXPECT_EQ(head.stage().position(), 0);
  enable->set(false);  // physically high: enabled
  EXPECT_TRUE(head.stage().enabled());
  // An active-low device configured in the head is driven correctly by an
  // active-low request; inputs report logical levels.
  HeadConfig c = test::smallHead();
  c.lines.home.active_low = true;
  VirtualHead head2(c, test::planeScene());
  drivers::LineSpec home_spec = LineDriver::spec("home");
  home_spec.active_low = true;
  EXPECT_TRUE(head2.gpio().requestInput(home_spec)->get());
  VirtualHead head3(c, test::planeScene());
  EXPECT_FALSE(head3.gpio().requestInput(LineDriver::spec("home"))->get());
}

TEST(SimGpio, InjectedFaultIsReportedWithEdges) {
  VirtualHead head(test::smallHead(), test::planeScene());
  auto fault = head.gpio().requestInput(LineDriver::spec("fault"));
  head.clock().sleepUntil(5ms);
  head.setStageFault(true);
  EXPECT_TRUE(fault->get());
  const auto e = fault->waitEdge(1ms);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->edge, drivers::Edge::Rising);
  EXPECT_EQ(e->timestamp, 5ms);
}

}  // namespace
}  // namespace cylscan::sim
