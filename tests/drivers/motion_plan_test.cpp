// SPDX-License-Identifier: Apache-2.0
// The planner: exact step counts, monotone deadlines, speed and acceleration
// within the configured trapezoid (measured from consecutive deadlines, as
// the stage feels them), triangles for short moves, sweeps with triggers at
// exact step counts.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "drivers/motion_plan.hpp"

namespace cylscan::drivers {
namespace {

struct Measured {
  double max_speed = 0;    // steps/s
  double max_accel = 0;    // steps/s², |Δv| over the time between the speeds' midpoints
  double accel_bound = 0;  // the configured acceleration plus the rounding allowance
  double first_speed = 0, last_speed = 0;
};

// Speeds of consecutive pulses v_i = 1/(t_i − t_{i−1}) are the profile's
// speed at the middle of each interval, so the acceleration is their change
// over the time between those middles. Deadlines are rounded to 1 ns: a
// speed v carries an error up to v²·1 ns, hence the allowance.
Measured measure(const StepSchedule& s, double accel) {
  Measured m;
  m.accel_bound = accel;
  double previous = 0;
  for (std::size_t i = 1; i < s.step_ns.size(); ++i) {
    const double dt = static_cast<double>(s.step_ns[i] - s.step_ns[i - 1]) * 1e-9;
    const double v = 1 / dt;
    m.max_speed = std::max(m.max_speed, v);
    if (i == 1) m.first_speed = v;
    m.last_speed = v;
    if (i >= 2) {
      const double dt_prev = static_cast<double>(s.step_ns[i - 1] - s.step_ns[i - 2]) * 1e-9;
      const double a = std::abs(v - previous) / ((dt + dt_prev) / 2);
      m.max_accel = std::max(m.max_accel, a);
      m.accel_bound = std::max(m.accel_bound, accel + 2 * v * v * 1e-9 / ((dt + dt_prev) / 2));
    }
    previous = v;
  }
  return m;
}

StageConfig config() {
  return StageConfig{};  // 250 steps/°, 20°/s, 80°/s², start 2°/s
}

TEST(MotionPlan, TrapezoidHasExactCountsAndRespectsTheLimits) {
  const StageConfig c = config();
  const double spd = c.stepsPerDeg();
  for (const std::int64_t steps : {5000, -5000, 12345}) {
    const StepSchedule s = planMove(c, steps);
    ASSERT_EQ(s.steps(), std::abs(steps));
    EXPECT_EQ(s.forward, steps > 0);
    EXPECT_EQ(s.step_ns.front(), std::llround(c.dir_setup_us * 1e3));
    EXPECT_EQ(s.step_high_ns, std::llround(c.step_pulse_us * 1e3));
    for (std::size_t i = 1; i < s.step_ns.size(); ++i)
      ASSERT_GT(s.step_ns[i], s.step_ns[i - 1] + s.step_high_ns);
    const Measured m = measure(s, c.accel_deg_s2 * spd);
    EXPECT_LE(m.max_speed, c.max_speed_deg_s * spd * (1 + 1e-6));
    EXPECT_GT(m.max_speed, c.max_speed_deg_s * spd * 0.999);  // it does reach the cruise
    EXPECT_LE(m.max_accel, m.accel_bound);
    EXPECT_GT(m.max_accel, 0.95 * c.accel_deg_s2 * spd);  // and does accelerate at the limit
    // Starts and ends near the start speed (the first interval's mean speed).
    EXPECT_LT(m.first_speed, 1.2 * c.start_speed_deg_s * spd);
    EXPECT_LT(m.last_speed, 1.2 * c.start_speed_deg_s * spd);
    // Symmetric: the intervals read the same backwards (within rounding).
    const std::size_t n = s.step_ns.size();
    for (std::size_t i = 1; i < n; ++i) {
      const std::int64_t forward = s.step_ns[i] - s.step_ns[i - 1];
      const std::int64_t backward = s.step_ns[n - i] - s.step_ns[n - i - 1];
      ASSERT_LE(std::abs(forward - backward), 2) << i;
    }
  }
}

TEST(MotionPlan, ShortMoveIsATriangleBelowTheMaximumSpeed) {
  const StageConfig c = config();
  const double spd = c.stepsPerDeg();
  // Full ramp to 20°/s needs (v² − v0²)/2a ≈ 619 steps each way.
  const StepSchedule s = planMove(c, 600);
  ASSERT_EQ(s.steps(), 600);
  const Measured m = measure(s, c.accel_deg_s2 * spd);
  const double peak =
      std::sqrt(std::pow(c.start_speed_deg_s * spd, 2) + c.accel_deg_s2 * spd * 599);
  EXPECT_LT(m.max_speed, c.max_speed_deg_s * spd * 0.9);
  EXPECT_NEAR(m.max_speed, peak, 0.01 * peak);
  EXPECT_LE(m.max_accel, m.accel_bound);
  // No constant-speed part: the intervals shrink to the middle, then grow.
  for (std::size_t i = 2; i < 300; ++i)
    EXPECT_LT(s.step_ns[i] - s.step_ns[i - 1], s.step_ns[i - 1] - s.step_ns[i - 2]) << i;
}

TEST(MotionPlan, TinyAndSlowMoves) {
  const StageConfig c = config();
  EXPECT_EQ(planMove(c, 0).steps(), 0);
  EXPECT_EQ(planMove(c, 0).durationNs(), 0);
  const StepSchedule one = planMove(c, -1);
  ASSERT_EQ(one.steps(), 1);
  EXPECT_FALSE(one.forward);
  // Below the start speed: a constant rate, exactly 1/v apart.
  const StepSchedule slow = planMove(c, 10, 0.5);  // 125 steps/s = 8 ms
  for (std::size_t i = 1; i < slow.step_ns.size(); ++i)
    EXPECT_EQ(slow.step_ns[i] - slow.step_ns[i - 1], 8'000'000);
  EXPECT_THROW(planMove(c, 10, 25.0), std::invalid_argument);  // above the maximum
  StageConfig bad = c;
  bad.step_pulse_us = 300;  // longer than the 200 µs between steps at 20°/s
  EXPECT_THROW(planMove(bad, 5000), std::invalid_argument);
  bad = c;
  bad.accel_deg_s2 = -1;
  EXPECT_THROW(planMove(bad, 10), std::invalid_argument);
}

TEST(MotionPlan, DeadlinesComeFromTheirIndexWithoutDrift) {
  // A long cruise: step i of the constant part is exactly i/v after its start.
  const StageConfig c = config();
  const StepSchedule s = planMove(c, 200000);  // 800°: 190 s at 5000 steps/s
  const std::size_t a = 1000, b = 199000;      // both in the cruise
  EXPECT_NEAR(static_cast<double>(s.step_ns[b] - s.step_ns[a]), (b - a) * 1e9 / 5000.0, 1.0);
}

TEST(MotionPlan, SweepFiresTriggersAtExactStepCountsAtConstantSpeed) {
  const StageConfig c = config();
  const double spd = c.stepsPerDeg();
  SweepRequest r;
  r.direction = -1;
  r.speed_deg_s = 10.0;  // 2500 steps/s
  r.range_steps = 1250;
  for (int k = 0; k <= 25; ++k)
    r.trigger_offsets.push_back(50 * k);
  const SweepPlan p = planSweep(c, r);
  EXPECT_EQ(p.run_up_steps, sweepRunUpSteps(c, r.speed_deg_s));
  // The ramp: (v² − v0²)/2a = (2500² − 500²)/(2·20000) = 150 steps exactly.
  EXPECT_EQ(p.run_up_steps, 151);
  EXPECT_EQ(p.run_out_steps, 150);
  const StepSchedule& s = p.schedule;
  EXPECT_FALSE(s.forward);
  ASSERT_EQ(s.steps(), p.run_up_steps + r.range_steps + p.run_out_steps);
  ASSERT_EQ(s.triggers.size(), r.trigger_offsets.size());
  for (std::size_t i = 0; i < s.triggers.size(); ++i) {
    const std::int64_t count = p.run_up_steps + r.trigger_offsets[i];
    EXPECT_EQ(s.triggers[i].step_count, count);
    EXPECT_EQ(s.triggers[i].time_ns, s.step_ns[static_cast<std::size_t>(count - 1)]);
  }
  // Constant speed through the range: every interval 400 µs (±1 ns rounding).
  for (std::int64_t k = p.run_up_steps; k < p.run_up_steps + r.range_steps; ++k) {
    const auto i = static_cast<std::size_t>(k);
    ASSERT_NEAR(static_cast<double>(s.step_ns[i] - s.step_ns[i - 1]), 400'000.0, 1.0) << k;
  }
  const Measured m = measure(s, c.accel_deg_s2 * spd);
  EXPECT_LE(m.max_speed, 2500 * (1 + 1e-6));
  EXPECT_LE(m.max_accel, m.accel_bound);
  // Triggers 20 ms apart, each 10 µs high.
  EXPECT_EQ(s.trigger_high_ns, 10'000);
  EXPECT_NEAR(static_cast<double>(s.triggers[1].time_ns - s.triggers[0].time_ns), 20e6, 1.0);
}

TEST(MotionPlan, SweepLeadAndInvalidRequests) {
  const StageConfig c = config();
  SweepRequest r;
  r.speed_deg_s = 10.0;
  r.range_steps = 100;
  r.trigger_offsets = {0, 100};
  r.trigger_lead_us = 5020;  // latency 20 µs + half of a 10 ms exposure
  const SweepPlan p = planSweep(c, r);
  EXPECT_EQ(p.schedule.triggers[0].time_ns,
            p.schedule.step_ns[static_cast<std::size_t>(p.run_up_steps - 1)] - 5'020'000);
  r.trigger_offsets = {0, 101};
  EXPECT_THROW(planSweep(c, r), std::invalid_argument);  // beyond the range
  r.trigger_offsets = {10, 10};
  EXPECT_THROW(planSweep(c, r), std::invalid_argument);  // not ascending
  r.trigger_offsets = {0, 1};
  r.trigger_pulse_us = 500;  // longer than the 400 µs between them
  EXPECT_THROW(planSweep(c, r), std::invalid_argument);
  r.trigger_pulse_us = 10;
  r.speed_deg_s = 30;
  EXPECT_THROW(planSweep(c, r), std::invalid_argument);
}

TEST(MotionPlan, StopRampsDownToTheStartSpeed) {
  const StageConfig c = config();
  const double spd = c.stepsPerDeg();
  const double v = 10 * spd;  // 2500 steps/s
  const StepSchedule s = planStop(c, true, v);
  EXPECT_EQ(s.steps(), 150);  // (2500² − 500²)/(2·20000)
  EXPECT_NEAR(static_cast<double>(s.step_ns[0]), 1e9 / v, 1e9 / v * 0.01);
  const Measured m = measure(s, c.accel_deg_s2 * spd);
  EXPECT_LE(m.max_speed, v);
  EXPECT_LE(m.max_accel, m.accel_bound);
  EXPECT_LT(m.last_speed, 1.05 * c.start_speed_deg_s * spd);
  EXPECT_EQ(planStop(c, true, 400).steps(), 0);  // already a safe stop
}

}  // namespace
}  // namespace cylscan::drivers
