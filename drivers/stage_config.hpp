// SPDX-License-Identifier: Apache-2.0
// The rotation stage as the firmware drives it: its step geometry, the motion
// limits the planner respects, and the homing procedure. Read from the
// [stage] section of a board profile (board/<name>/board.toml).
#pragma once

#include <cmath>
#include <cstdint>
#include <optional>

namespace cylscan::drivers {

struct StageConfig {
  // Step geometry: executed angle = steps / stepsPerDeg().
  int full_steps_per_rev = 200;
  int microsteps = 10;
  double gear_ratio = 45.0;  // 200 × 10 × 45 = 90000 steps/rev = 0.004° per step

  // Motion limits of the planned trapezoid (below the stage's pull-out limits).
  double max_speed_deg_s = 20.0;
  double accel_deg_s2 = 80.0;
  double start_speed_deg_s = 2.0;  // first and last step rate of every move

  // Step/dir electrical timing.
  double step_pulse_us = 5.0;  // high time of a step pulse
  double dir_setup_us = 20.0;  // dir change to first step edge
  double enable_settle_ms = 10.0;

  // Settling before a stop-and-go exposure (the stage rings after a stop).
  double settle_ms = 100.0;

  // Homing: seek the home edge, back off, approach slowly, set zero there.
  int home_direction = -1;  // +1 or -1: the direction of the seek
  double home_seek_speed_deg_s = 10.0;
  double home_approach_speed_deg_s = 0.5;
  double home_backoff_deg = 1.0;
  double home_max_travel_deg = 370.0;  // no edge within this travel: "home switch never fired"
  double home_offset_deg = 0.0;        // angle of the home edge in the stage's zero

  // A home edge, passed on the way or sought again, is within this many steps
  // of where the executed step count puts it; more means lost steps.
  int step_check_tolerance_steps = 2;

  double stepsPerDeg() const {
    return static_cast<double>(full_steps_per_rev) * microsteps * gear_ratio / 360.0;
  }
  // Steps of one turn of the stage, when that is a whole number: the stage can
  // then keep its count modulo a turn and reach a step by either way round.
  std::optional<std::int64_t> stepsPerTurn() const {
    const double turn = static_cast<double>(full_steps_per_rev) * microsteps * gear_ratio;
    const double whole = std::round(turn);
    if (whole < 1 || std::abs(turn - whole) > 1e-9 * whole) return std::nullopt;
    return static_cast<std::int64_t>(whole);
  }
};

// Throws std::invalid_argument naming the field when a value is impossible.
void validate(const StageConfig& config);

}  // namespace cylscan::drivers
