// SPDX-License-Identifier: Apache-2.0
// The [faults] table of a head file (drivers/sim/head_config.hpp) and the
// stage model's scheduled faults behind it: a lost step after a count of
// pulses, a home switch that never fires.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include <toml++/toml.h>

#include "drivers/sim/head_config.hpp"
#include "drivers/sim/stage.hpp"
#include "drivers/toml_reader.hpp"

namespace cylscan::sim {
namespace {

using drivers::ConfigError;
using std::chrono::seconds;

HeadConfig parse(const std::string& text) {
  return parseHeadConfig(toml::parse(text), "head.toml");
}

TEST(FaultConfig, NoFaultsByDefault) {
  EXPECT_EQ(parse("").faults, FaultConfig{});
  EXPECT_EQ(defaultHeadConfig().faults, FaultConfig{});
}

TEST(FaultConfig, ReadsEveryKey) {
  const FaultConfig f = parse(
                            "[faults]\ncamera = \"aux\"\ndrop_frames = 2\ndelay_first_frame_ms = "
                            "1500.5\ncorrupt_frames = 3\nlose_steps_after = 100\nlose_steps = "
                            "4\nhome_switch = false\n")
                            .faults;
  EXPECT_EQ(f.camera, "aux");
  EXPECT_EQ(f.drop_frames, 2);
  EXPECT_DOUBLE_EQ(f.delay_first_frame_ms, 1500.5);
  EXPECT_EQ(f.corrupt_frames, 3);
  EXPECT_EQ(f.lose_steps_after, 100);
  EXPECT_EQ(f.lose_steps, 4);
  EXPECT_FALSE(f.home_switch);
}

TEST(FaultConfig, BadValuesNameTheKey) {
  const auto expectError = [](const std::string& text, const std::string& key) {
    try {
      parse(text);
      FAIL() << "no error for " << text;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  expectError("[faults]\ndrop_frames = -1\n", "faults.drop_frames");
  expectError("[faults]\ncorrupt_frames = -2\n", "faults.corrupt_frames");
  expectError("[faults]\nlose_steps = -1\n", "faults.lose_steps");
  expectError("[faults]\ndelay_first_frame_ms = -5.0\n", "faults.delay_first_frame_ms");
  expectError("[faults]\nhome_switch = 3\n", "faults.home_switch");
  expectError("[faults]\nbogus = 1\n", "faults.bogus");
  expectError("[faults]\ncamera = \"nope\"\n", "faults.camera");
}

// Pulses slower than the start rate are always followed, so every loss is
// the scheduled one.
TEST(FaultConfig, StageLosesTheStepsAfterTheCount) {
  StageParams p;
  StageModel stage(p);
  stage.loseStepsAfter(5, 1);
  stage.setEnabled(true, seconds(0));
  for (int i = 1; i <= 8; ++i)
    stage.stepPulse(seconds(i));
  EXPECT_EQ(stage.counters().pulses, 8u);
  EXPECT_EQ(stage.counters().lost, 1u);
  EXPECT_EQ(stage.position(), 7);
  EXPECT_TRUE(stage.fault()) << "a lost step sets the fault output";
}

TEST(FaultConfig, ABrokenHomeSwitchIsNeverActive) {
  StageParams p;  // starts at home_deg: the switch is active
  StageModel working(p);
  EXPECT_TRUE(working.homeActive());
  StageModel broken(p);
  broken.breakHomeSwitch();
  EXPECT_FALSE(broken.homeActive());
  broken.setEnabled(true, seconds(0));
  broken.setDirection(false);
  for (int i = 1; i <= 3; ++i)  // back and forth across home
    broken.stepPulse(seconds(i));
  broken.setDirection(true);
  for (int i = 4; i <= 9; ++i)
    broken.stepPulse(seconds(i));
  EXPECT_FALSE(broken.homeActive());
  EXPECT_EQ(broken.edgeCount(), 0u);
}

}  // namespace
}  // namespace cylscan::sim
