// SPDX-License-Identifier: Apache-2.0
// Motion planning, pure (no I/O): a move of the rotation stage becomes a step
// schedule with the exact number of step pulses and each pulse's deadline,
// planned before anything is executed (StepExecutor emits it).
//
// Profiles: the step at profile position x (x = 0 for the first step, one
// unit per step) comes at the time the trapezoid reaches x: from the start
// speed v0 with constant acceleration a to the peak speed, constant speed,
// and symmetrically down to v0 (a triangle when the move is too short to
// reach the maximum speed). Each deadline is computed from its index in
// closed form and rounded to the nanosecond, so nothing drifts.
#pragma once

#include <cstdint>
#include <vector>

#include "drivers/stage_config.hpp"

namespace cylscan::drivers {

// A trigger pulse of a sweep: fires when `step_count` steps of the move have
// been executed (right after that step's rising edge when the lead is 0).
struct TriggerPulse {
  std::int64_t step_count = 0;
  std::int64_t time_ns = 0;  // rising edge, from the move start
};

struct StepSchedule {
  bool forward = true;            // the dir line's level: active = + direction
  std::int64_t step_high_ns = 0;  // high time of every step pulse
  std::int64_t trigger_high_ns = 0;
  // Rising edge of step i + 1, from the move start (when dir is set);
  // strictly increasing, the first one at least the dir setup time.
  std::vector<std::int64_t> step_ns;
  std::vector<TriggerPulse> triggers;  // in time order
  // The ramp the executor may re-accelerate with after a late edge (see
  // StepExecutor): the move's start/stop rate and acceleration, in steps/s
  // and steps/s². 0: the schedule came without them (the executor then only
  // delays the rest of the schedule, never bursts).
  double start_rate_steps_s = 0;
  double accel_steps_s2 = 0;
  // How late (in steps at the planned rate) an edge may be and still be
  // caught up on plan: half a full step, the lag a stepper's rotor absorbs.
  double lag_tolerance_steps = 0.5;

  std::int64_t steps() const { return static_cast<std::int64_t>(step_ns.size()); }
  int direction() const { return forward ? 1 : -1; }
  // The last falling edge, from the move start (0 for an empty schedule).
  std::int64_t durationNs() const;
};

// A relative move of `steps` (sign = direction) with the configured
// trapezoid, or with the cruise speed `speed_deg_s` (<= max speed; a speed at
// or below the start speed gives a constant rate). Throws
// std::invalid_argument for an impossible configuration or speed.
StepSchedule planMove(const StageConfig& config, std::int64_t steps);
StepSchedule planMove(const StageConfig& config, std::int64_t steps, double speed_deg_s);

// Continuous motion: ramp up, a range at constant speed with triggers at
// exact step counts, ramp down.
struct SweepRequest {
  int direction = 1;                          // +1 or -1
  double speed_deg_s = 0;                     // constant speed in the range (<= max speed)
  std::int64_t range_steps = 0;               // length of the constant-speed range
  std::vector<std::int64_t> trigger_offsets;  // steps into the range, ascending, <= range_steps
  double trigger_pulse_us = 10.0;             // trigger high time
  double trigger_lead_us = 0.0;  // fire this long before the step (latency, exposure/2)
};

struct SweepPlan {
  StepSchedule schedule;
  // Steps of the ramp up: the range starts once run_up_steps steps are
  // executed, and trigger i fires at run_up_steps + trigger_offsets[i].
  std::int64_t run_up_steps = 0;
  std::int64_t run_out_steps = 0;  // steps of the ramp down after the range
};

// The run-up of a sweep at `speed_deg_s` (to position the stage before it).
std::int64_t sweepRunUpSteps(const StageConfig& config, double speed_deg_s);
SweepPlan planSweep(const StageConfig& config, const SweepRequest& request);

// An early stop (a seek that found its edge): the steps that ramp down from
// `speed_steps_s` to the start speed, timed from the last executed step, in
// the same direction. Empty when that speed is already a safe stop.
StepSchedule planStop(const StageConfig& config, bool forward, double speed_steps_s);

}  // namespace cylscan::drivers
