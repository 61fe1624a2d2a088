// SPDX-License-Identifier: Apache-2.0
// Helpers for the driver tests: a small virtual head, the firmware's view of
// its stage (StageConfig), the line specs, and an output line that counts.
#pragma once

#include <atomic>
#include <string>

#include "drivers/gpio.hpp"
#include "drivers/rotation_stage.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "drivers/stage_config.hpp"

namespace cylscan::drivers::test {

// The default head at 64 × 48, noiseless, with the stage powered up at
// `initial_deg` (0: on the home switch).
inline sim::HeadConfig smallHead(double initial_deg = 3.0) {
  sim::HeadConfig c = sim::withResolution(sim::defaultHeadConfig(), 64, 48);
  c.noise.scale = 0;
  c.stage.initial_deg = initial_deg;
  return c;
}

inline sim::Scene planeScene() {
  sim::Scene s;
  s.name = "plane";
  s.objects.push_back(
      {"plane", sim::Plane{sim::Vec3(0, 0, 580), sim::Vec3(0, 0, -1), std::nullopt}, 0.8});
  return s;
}

// The firmware's stage for that head: the same step geometry, and the home
// edge (met coming from + with home_direction −1: the window's upper edge,
// at +home_window/2) declared at that angle, so the firmware's zero is the
// head's zero.
inline StageConfig stageFor(const sim::HeadConfig& head) {
  StageConfig c;
  c.full_steps_per_rev = head.stage.full_steps_per_rev;
  c.microsteps = head.stage.microsteps;
  c.gear_ratio = head.stage.gear_ratio;
  c.home_direction = -1;
  c.home_offset_deg = head.stage.home_window_deg / 2;
  return c;
}

inline LineSpec spec(const char* name) {
  LineSpec s;
  s.name = name;
  s.role = name;
  return s;
}

inline StageLineSpecs stageSpecs(bool with_fault) {
  StageLineSpecs s{spec("step"), spec("dir"), spec("enable"), spec("home"), std::nullopt};
  if (with_fault) s.fault = spec("fault");
  return s;
}

// An output line that only counts rising edges (for the real clock).
class CountingLine final : public OutputLine {
 public:
  void set(bool active) override {
    if (active && !level_) rising.fetch_add(1, std::memory_order_relaxed);
    level_ = active;
  }
  std::atomic<long> rising{0};

 private:
  bool level_ = false;
};

}  // namespace cylscan::drivers::test
