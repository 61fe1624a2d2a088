// SPDX-License-Identifier: Apache-2.0
#include "drivers/motion_plan.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace cylscan::drivers {

namespace {

std::int64_t toNs(double seconds) {
  return std::llround(seconds * 1e9);
}

std::int64_t usToNs(double us) {
  return std::llround(us * 1e3);
}

// A symmetric speed profile over the profile positions x in [0, length]:
// from v0 up to vp with acceleration a over `ramp` units, constant vp, and
// down again over the last `ramp` units.
class Profile {
 public:
  Profile(double v0, double vp, double a, double ramp, double length)
      : v0_(v0), vp_(vp), a_(a), ramp_(ramp), length_(length) {
    ramp_time_ = ramp_ > 0 ? rampTime(ramp_) : 0.0;
    total_ = 2 * ramp_time_ + (length_ - 2 * ramp_) / vp_;
  }

  // The time at which the profile reaches x.
  double time(double x) const {
    if (x <= ramp_ && ramp_ > 0) return rampTime(x);
    if (x <= length_ - ramp_) return ramp_time_ + (x - ramp_) / vp_;
    return total_ - rampTime(length_ - x);
  }

 private:
  // Time to cover y from v0 at acceleration a: the root of v0 t + a t²/2 = y,
  // in the form without cancellation.
  double rampTime(double y) const { return 2 * y / (v0_ + std::sqrt(v0_ * v0_ + 2 * a_ * y)); }

  double v0_, vp_, a_, ramp_, length_;
  double ramp_time_ = 0, total_ = 0;
};

void checkSpeed(const StageConfig& config, double speed_deg_s, const char* what) {
  if (!std::isfinite(speed_deg_s) || speed_deg_s <= 0 ||
      speed_deg_s > config.max_speed_deg_s * (1 + 1e-12)) {
    throw std::invalid_argument(
        std::string(what) + ": speed " + std::to_string(speed_deg_s) +
        "°/s outside (0, max_speed_deg_s = " + std::to_string(config.max_speed_deg_s) + "]");
  }
}

// Fills the step deadlines from a profile; checks the pulse fits.
void fill(StepSchedule& s, const StageConfig& config, const Profile& p, std::int64_t steps,
          std::int64_t offset_ns) {
  s.step_high_ns = usToNs(config.step_pulse_us);
  s.start_rate_steps_s = config.start_speed_deg_s * config.stepsPerDeg();
  s.accel_steps_s2 = config.accel_deg_s2 * config.stepsPerDeg();
  s.lag_tolerance_steps = std::max(0.5, config.microsteps / 2.0);
  s.step_ns.resize(static_cast<std::size_t>(steps));
  for (std::int64_t i = 0; i < steps; ++i) {
    s.step_ns[static_cast<std::size_t>(i)] = offset_ns + toNs(p.time(static_cast<double>(i)));
  }
  for (std::size_t i = 1; i < s.step_ns.size(); ++i) {
    if (s.step_ns[i] - s.step_ns[i - 1] <= s.step_high_ns) {
      throw std::invalid_argument(
          "motion plan: step_pulse_us = " + std::to_string(config.step_pulse_us) +
          " does not fit between steps at this speed");
    }
  }
}

}  // namespace

std::int64_t StepSchedule::durationNs() const {
  std::int64_t end = step_ns.empty() ? 0 : step_ns.back() + step_high_ns;
  if (!triggers.empty()) end = std::max(end, triggers.back().time_ns + trigger_high_ns);
  return end;
}

StepSchedule planMove(const StageConfig& config, std::int64_t steps) {
  return planMove(config, steps, config.max_speed_deg_s);
}

StepSchedule planMove(const StageConfig& config, std::int64_t steps, double speed_deg_s) {
  validate(config);
  checkSpeed(config, speed_deg_s, "planMove");
  StepSchedule s;
  s.forward = steps >= 0;
  const std::int64_t n = steps >= 0 ? steps : -steps;
  if (n == 0) return s;
  const double spd = config.stepsPerDeg();
  const double v0 = config.start_speed_deg_s * spd;
  const double vmax = speed_deg_s * spd;
  const double a = config.accel_deg_s2 * spd;
  const auto length = static_cast<double>(n - 1);  // from the first step to the last
  double peak = vmax, ramp = 0;
  if (vmax > v0) {
    ramp = (vmax * vmax - v0 * v0) / (2 * a);
    if (2 * ramp > length) {  // a triangle: the peak where the ramps meet
      ramp = length / 2;
      peak = std::sqrt(v0 * v0 + a * length);
    }
  }
  fill(s, config, Profile(std::min(v0, peak), peak, a, ramp, length), n,
       usToNs(config.dir_setup_us));
  return s;
}

std::int64_t sweepRunUpSteps(const StageConfig& config, double speed_deg_s) {
  validate(config);
  checkSpeed(config, speed_deg_s, "sweep");
  const double spd = config.stepsPerDeg();
  const double v0 = config.start_speed_deg_s * spd, v = speed_deg_s * spd;
  const double ramp = v > v0 ? (v * v - v0 * v0) / (2 * config.accel_deg_s2 * spd) : 0.0;
  // The ramp spans whole steps (a slightly gentler acceleration), and the
  // range begins with the step at the end of the ramp.
  return static_cast<std::int64_t>(std::ceil(ramp - 1e-9)) + 1;
}

SweepPlan planSweep(const StageConfig& config, const SweepRequest& r) {
  validate(config);
  checkSpeed(config, r.speed_deg_s, "planSweep");
  if (r.direction != 1 && r.direction != -1) {
    throw std::invalid_argument("planSweep: direction must be +1 or -1");
  }
  if (r.range_steps < 0) throw std::invalid_argument("planSweep: range_steps must be >= 0");
  if (!(r.trigger_pulse_us > 0) || !(r.trigger_lead_us >= 0)) {
    throw std::invalid_argument("planSweep: trigger_pulse_us must be > 0, trigger_lead_us >= 0");
  }
  for (std::size_t i = 0; i < r.trigger_offsets.size(); ++i) {
    const std::int64_t o = r.trigger_offsets[i];
    if (o < 0 || o > r.range_steps || (i > 0 && o <= r.trigger_offsets[i - 1])) {
      throw std::invalid_argument(
          "planSweep: trigger offsets must ascend strictly within [0, range_steps]");
    }
  }
  const double spd = config.stepsPerDeg();
  const double v0 = config.start_speed_deg_s * spd, v = r.speed_deg_s * spd;
  SweepPlan plan;
  plan.run_up_steps = sweepRunUpSteps(config, r.speed_deg_s);
  const std::int64_t ramp = plan.run_up_steps - 1;
  plan.run_out_steps = ramp;
  const std::int64_t total = plan.run_up_steps + r.range_steps + plan.run_out_steps;
  // The acceleration that ramps from v0 to v over exactly `ramp` steps (<= accel).
  const double a = ramp > 0 ? (v * v - v0 * v0) / (2 * static_cast<double>(ramp)) : 1.0;
  StepSchedule& s = plan.schedule;
  s.forward = r.direction > 0;
  fill(s, config,
       Profile(std::min(v0, v), v, a, static_cast<double>(ramp), static_cast<double>(total - 1)),
       total, usToNs(config.dir_setup_us));
  s.trigger_high_ns = usToNs(r.trigger_pulse_us);
  const std::int64_t lead = usToNs(r.trigger_lead_us);
  for (const std::int64_t o : r.trigger_offsets) {
    const std::int64_t count = plan.run_up_steps + o;
    const std::int64_t t = s.step_ns[static_cast<std::size_t>(count - 1)] - lead;
    if (t < 0) throw std::invalid_argument("planSweep: trigger_lead_us reaches before the move");
    if (!s.triggers.empty() && t - s.triggers.back().time_ns <= s.trigger_high_ns) {
      throw std::invalid_argument("planSweep: trigger pulses overlap (offsets too close)");
    }
    s.triggers.push_back({count, t});
  }
  return plan;
}

StepSchedule planStop(const StageConfig& config, bool forward, double speed_steps_s) {
  validate(config);
  StepSchedule s;
  s.forward = forward;
  s.step_high_ns = usToNs(config.step_pulse_us);
  const double spd = config.stepsPerDeg();
  const double v0 = config.start_speed_deg_s * spd, a = config.accel_deg_s2 * spd;
  s.start_rate_steps_s = v0;
  s.accel_steps_s2 = a;
  s.lag_tolerance_steps = std::max(0.5, config.microsteps / 2.0);
  const double v = speed_steps_s;
  if (!(v > v0) || !std::isfinite(v)) return s;
  const double ramp = (v * v - v0 * v0) / (2 * a);
  const auto n = static_cast<std::int64_t>(std::ceil(ramp - 1e-9));
  const double t_ramp = (v - v0) / a;
  s.step_ns.resize(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i) {
    const auto x = static_cast<double>(i + 1);  // one step after the last one, ...
    const double t = x <= ramp ? 2 * x / (v + std::sqrt(std::max(0.0, v * v - 2 * a * x)))
                               : t_ramp + (x - ramp) / v0;
    s.step_ns[static_cast<std::size_t>(i)] = toNs(t);
  }
  return s;
}

}  // namespace cylscan::drivers
