// SPDX-License-Identifier: Apache-2.0
// The stage controller on the virtual head: homing finds the head's zero,
// moves execute exactly, lost steps (injected, or from driving the stage
// faster than it can follow) are caught by the step-count check, a home
// switch that never fires and the fault input give clear errors, and every
// failure leaves the stage disabled.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "drivers/rotation_stage.hpp"
#include "drivers_test_support.hpp"

namespace cylscan::drivers {
namespace {

using test::planeScene;
using test::smallHead;
using test::stageFor;
using test::stageSpecs;

void expectStageError(const std::function<void()>& f, const std::string& text) {
  try {
    f();
    ADD_FAILURE() << "no StageError (expected one saying '" << text << "')";
  } catch (const StageError& e) {
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("disabled"), std::string::npos) << e.what();
  }
}

struct Rig {
  explicit Rig(double initial_deg = 3.0, bool with_fault = true, StageConfig* config = nullptr)
      : head(smallHead(initial_deg), planeScene()),
        stage(config ? *config : stageFor(head.config()), head.clock(), head.gpio(),
              stageSpecs(with_fault)) {}
  sim::VirtualHead head;
  RotationStage stage;
};

TEST(RotationStage, HomingFindsTheHeadsZero) {
  for (const double initial : {3.0, 0.0, 200.0, 359.5}) {  // 0: powered up on the switch
    Rig rig(initial);
    rig.stage.enable();
    EXPECT_TRUE(rig.head.stage().enabled());
    const HomeResult h = rig.stage.home();
    EXPECT_TRUE(rig.stage.homed());
    // The firmware's count and the head's true position agree exactly.
    EXPECT_EQ(rig.head.stage().position(), rig.stage.position()) << initial;
    EXPECT_EQ(rig.head.stage().counters().lost, 0u);
    EXPECT_GT(h.edge_time.count(), 0);
    rig.stage.moveTo(0.0);
    EXPECT_EQ(rig.head.stage().position(), 0);
    EXPECT_EQ(rig.stage.angleDeg(), 0.0);
    EXPECT_EQ(rig.head.stage().counters().lost, 0u);
  }
}

TEST(RotationStage, MovesReportTheExecutedPosition) {
  Rig rig;
  rig.stage.enable();
  rig.stage.home();
  EXPECT_EQ(rig.stage.moveTo(90.0), 22500);
  EXPECT_EQ(rig.head.stage().position(), 22500);
  EXPECT_EQ(rig.stage.moveBySteps(-1234), 21266);
  EXPECT_EQ(rig.head.stage().position(), 21266);
  EXPECT_DOUBLE_EQ(rig.stage.angleDeg(), 21266 / 250.0);
  EXPECT_EQ(rig.stage.moveTo(12.3456), 3086);  // the nearest step: 12.344°
  EXPECT_EQ(rig.head.stage().counters().lost, 0u);
  const StepCheck c = rig.stage.verifyStepCount();
  EXPECT_EQ(c.lostSteps(), 0);
}

TEST(RotationStage, MovesNeedEnableAndAngleNeedsHoming) {
  Rig rig;
  EXPECT_THROW(rig.stage.moveBySteps(10), StageError);
  rig.stage.enable();
  EXPECT_THROW(rig.stage.moveTo(10.0), StageError);
  EXPECT_THROW(rig.stage.verifyStepCount(), StageError);
  EXPECT_EQ(rig.stage.moveBySteps(10), 10);  // relative moves work before homing
}

TEST(RotationStage, InjectedLostStepsAreCaughtByTheStepCheck) {
  Rig rig(3.0, /*with_fault=*/false);  // no fault line: only the count can tell
  rig.stage.enable();
  rig.stage.home();
  rig.stage.moveTo(30.0);
  rig.head.loseSteps(7);
  rig.stage.moveTo(60.0);
  EXPECT_EQ(rig.stage.position(), 15000);
  EXPECT_EQ(rig.head.stage().position(), 15000 - 7);
  expectStageError([&] { rig.stage.verifyStepCount(); }, "lost 7 steps");
  EXPECT_FALSE(rig.head.stage().enabled());
  EXPECT_FALSE(rig.stage.enabled());
}

// A turn is 90000 steps: the stage reaches a step either way round, and every
// move that passes home checks the count against the edge of its direction
// (homing's edge moving down, the one homing's back-off met moving up).
TEST(RotationStage, PassingHomeChecksTheCountEitherWayRound) {
  Rig rig(3.0, /*with_fault=*/false);
  rig.stage.enable();
  rig.stage.home();
  rig.stage.moveTo(30.0);
  rig.stage.resetPassedChecks();
  const auto turnPosition = [&] { return ((rig.head.stage().position() % 90000) + 90000) % 90000; };
  EXPECT_TRUE(rig.stage.passesCheckedEdge(rig.stage.position(), -90 * 250));
  EXPECT_EQ(rig.stage.turnTo(300 * 250, -1), 75000);  // down past home
  EXPECT_EQ(turnPosition(), 75000);
  EXPECT_EQ(rig.stage.passedChecks(), 1);
  ASSERT_TRUE(rig.stage.lastPassedCheck());
  EXPECT_TRUE(rig.stage.lastPassedCheck()->passed);
  EXPECT_EQ(rig.stage.lastPassedCheck()->lostSteps(), 0);
  EXPECT_TRUE(rig.stage.passesCheckedEdge(rig.stage.position(), 90 * 250));
  EXPECT_EQ(rig.stage.turnTo(30 * 250, 1), 7500);  // up past home
  EXPECT_EQ(turnPosition(), 7500);
  EXPECT_EQ(rig.stage.passedChecks(), 2);
  EXPECT_EQ(rig.stage.lastPassedCheck()->lostSteps(), 0);
  // A move that stays clear of home checks nothing.
  EXPECT_FALSE(rig.stage.passesCheckedEdge(rig.stage.position(), 90 * 250));
  rig.stage.moveTo(120.0);
  EXPECT_EQ(rig.stage.passedChecks(), 2);
  // Steps lost on the way fail the next pass, naming them.
  // Within a step of 7: the switch's repeatability (σ 0.5 step) between the
  // pass that learned the edge and this one.
  rig.head.loseSteps(7);
  try {
    rig.stage.turnTo(30 * 250, 1);
    ADD_FAILURE() << "the lost steps went unnoticed";
  } catch (const StageError& e) {
    const std::string text = e.what();
    const auto at = text.find("lost ");
    ASSERT_NE(at, std::string::npos) << text;
    EXPECT_NEAR(std::stoi(text.substr(at + 5)), 7, 1) << text;
    EXPECT_NE(text.find("as the stage passes it"), std::string::npos) << text;
  }
  EXPECT_FALSE(rig.stage.homed());
  EXPECT_FALSE(rig.head.stage().enabled());
}

TEST(RotationStage, LossesWithinTheToleranceAreReported) {
  Rig rig(3.0, false);
  rig.stage.enable();
  rig.stage.home();
  rig.head.loseSteps(2);  // the tolerance
  rig.stage.moveTo(45.0);
  EXPECT_EQ(rig.stage.verifyStepCount().lostSteps(), 2);
  EXPECT_TRUE(rig.stage.enabled());
}

TEST(RotationStage, DrivingTooFastLosesStepsAndTheCheckCatchesIt) {
  StageConfig fast = stageFor(smallHead());
  fast.max_speed_deg_s = 45;  // the head's stage pulls out at 30°/s
  fast.accel_deg_s2 = 100;
  Rig rig(3.0, false, &fast);
  rig.stage.enable();
  rig.stage.home();
  rig.stage.moveTo(180.0);
  EXPECT_GT(rig.head.stage().counters().lost, 0u);
  expectStageError([&] { rig.stage.verifyStepCount(); }, "lost");
  EXPECT_FALSE(rig.head.stage().enabled());
}

TEST(RotationStage, WithTheFaultLineTooFastFailsDuringTheMove) {
  StageConfig fast = stageFor(smallHead());
  fast.max_speed_deg_s = 45;
  fast.accel_deg_s2 = 100;
  Rig rig(3.0, true, &fast);
  rig.stage.enable();
  rig.stage.home();
  const std::uint64_t pulses = rig.head.stage().counters().pulses;
  expectStageError([&] { rig.stage.moveTo(180.0); }, "fault input active during a move");
  EXPECT_FALSE(rig.head.stage().enabled());
  // It stopped right after the first lost step, not 45000 steps later.
  EXPECT_LT(rig.head.stage().counters().pulses - pulses, 45000u);
}

TEST(RotationStage, HomeSwitchThatNeverFires) {
  StageConfig c = stageFor(smallHead());
  c.home_max_travel_deg = 20;  // the switch is 40° away
  Rig rig(40.0, true, &c);
  rig.stage.enable();
  expectStageError([&] { rig.stage.home(); }, "home switch never fired within 20° of travel");
  EXPECT_FALSE(rig.head.stage().enabled());
  EXPECT_FALSE(rig.stage.homed());
  // It travelled the whole distance (and ramped down), no further.
  EXPECT_NEAR(rig.head.stage().angleDeg(), 20.0, 1.0);
}

TEST(RotationStage, HomeSwitchWithTheWrongPolarity) {
  // The board says active-high, the switch is active-low: it reads active
  // everywhere but at home.
  sim::HeadConfig h = smallHead(3.0);
  h.lines.home.active_low = true;
  sim::VirtualHead head(h, planeScene());
  RotationStage stage(stageFor(h), head.clock(), head.gpio(), stageSpecs(true));
  stage.enable();
  expectStageError([&] { stage.home(); }, "polarity");
  EXPECT_FALSE(head.stage().enabled());
}

TEST(RotationStage, StageFaultInputDisables) {
  Rig rig;
  rig.stage.enable();
  rig.stage.home();
  rig.head.setStageFault(true);
  expectStageError([&] { rig.stage.moveTo(10.0); }, "stage fault input active before a move");
  EXPECT_FALSE(rig.head.stage().enabled());
  EXPECT_THROW(rig.stage.moveTo(10.0), StageError);  // stays disabled
}

TEST(RotationStage, FaultDuringAMoveStopsIt) {
  Rig rig;
  rig.stage.enable();
  rig.stage.home();
  rig.head.loseSteps(1);  // the stage stalls: its fault output goes active
  const std::uint64_t pulses = rig.head.stage().counters().pulses;
  expectStageError([&] { rig.stage.moveTo(50.0); }, "after 1 of");
  EXPECT_EQ(rig.head.stage().counters().pulses - pulses, 1u);
  EXPECT_FALSE(rig.head.stage().enabled());
}

TEST(RotationStage, AbortFailsTheMoveAndDisables) {
  Rig rig;
  rig.stage.enable();
  rig.stage.abort();
  expectStageError([&] { rig.stage.moveBySteps(100); }, "aborted");
  EXPECT_FALSE(rig.head.stage().enabled());
  EXPECT_EQ(rig.head.stage().counters().pulses, 0u);
  rig.stage.enable();  // re-arms
  EXPECT_EQ(rig.stage.moveBySteps(100), 100);
}

TEST(RotationStage, DestructionDisables) {
  sim::VirtualHead head(smallHead(), planeScene());
  {
    RotationStage stage(stageFor(head.config()), head.clock(), head.gpio(), stageSpecs(true));
    stage.enable();
    EXPECT_TRUE(head.stage().enabled());
  }
  EXPECT_FALSE(head.stage().enabled());
}

TEST(RotationStage, SweepTriggersAtTheExecutedAngles) {
  Rig rig;
  rig.stage.enable();
  rig.stage.home();
  auto trigger = rig.head.gpio().requestOutput(test::spec("trigger"), false);
  SweepRequest r;
  r.direction = -1;
  r.speed_deg_s = 10;
  r.range_steps = 500;
  r.trigger_offsets = {0, 100, 200, 300, 400, 500};
  const PreparedSweep sweep = rig.stage.prepareSweep(10000, r);  // range from 40° down
  EXPECT_EQ(rig.head.stage().position(), sweep.start_position);
  EXPECT_EQ(sweep.start_position, 10000 + sweep.plan.run_up_steps);
  ASSERT_EQ(sweep.trigger_positions.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(sweep.trigger_positions[i], 10000 - 100 * static_cast<std::int64_t>(i));
    EXPECT_DOUBLE_EQ(sweep.trigger_angles_deg[i], sweep.trigger_positions[i] / 250.0);
  }
  rig.stage.runSweep(sweep, *trigger);
  EXPECT_EQ(rig.stage.position(), 10000 - 500 - sweep.plan.run_out_steps);
  EXPECT_EQ(rig.head.stage().position(), rig.stage.position());
  EXPECT_EQ(rig.stage.executor().triggerJitter().snapshot().count, 6u);
  // Not at its start any more: refused.
  EXPECT_THROW(rig.stage.runSweep(sweep, *trigger), StageError);
}

}  // namespace
}  // namespace cylscan::drivers
