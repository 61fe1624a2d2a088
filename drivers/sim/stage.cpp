// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/stage.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace cylscan::sim {

namespace {

void check(bool ok, const char* name, const char* fault) {
  if (!ok) throw std::invalid_argument(std::string("stage.") + name + ": " + fault);
}

double seconds(std::chrono::nanoseconds d) {
  return static_cast<double>(d.count()) * 1e-9;
}

}  // namespace

void validate(const StageParams& p) {
  check(p.full_steps_per_rev > 0, "full_steps_per_rev", "must be > 0");
  check(p.microsteps > 0 && p.microsteps <= 1024, "microsteps", "must be in [1, 1024]");
  check(p.gear_ratio > 0, "gear_ratio", "must be > 0");
  check(p.max_speed_deg_s > 0, "max_speed_deg_s", "must be > 0");
  check(p.max_accel_deg_s2 > 0, "max_accel_deg_s2", "must be > 0");
  check(p.start_speed_deg_s > 0 && p.start_speed_deg_s <= p.max_speed_deg_s, "start_speed_deg_s",
        "must be in (0, max_speed_deg_s]");
  check(p.home_window_deg > 0 && p.home_window_deg < 180, "home_window_deg", "must be in (0, 180)");
  check(p.settle_amplitude_deg >= 0, "settle_amplitude_deg", "must be >= 0");
  check(p.settle_tau_ms > 0, "settle_tau_ms", "must be > 0");
  check(p.settle_freq_hz > 0, "settle_freq_hz", "must be > 0");
  check(p.backlash_deg >= 0 && p.backlash_deg < 1, "backlash_deg", "must be in [0, 1)");
  check(p.home_repeatability_deg >= 0 && p.home_repeatability_deg < p.home_window_deg / 4,
        "home_repeatability_deg", "must be in [0, home_window_deg / 4)");
}

StageModel::StageModel(const StageParams& params)
    : params_(params), steps_per_deg_(params.stepsPerDeg()), home_rng_(params.home_seed) {
  validate(params_);
  position_ = std::llround(params_.initial_deg * steps_per_deg_);
  output_ = static_cast<double>(position_);
  half_backlash_ = params_.backlash_deg * steps_per_deg_ / 2;
  drawHomeOffset();
  home_ = homeAt(output_);
  history_.push({Nanoseconds{0}, output_, 0.0});
}

void StageModel::drawHomeOffset() {
  if (params_.home_repeatability_deg <= 0) return;
  std::normal_distribution<double> offset(0.0, params_.home_repeatability_deg);
  home_offset_deg_ = offset(home_rng_);
}

bool StageModel::homeAt(double position) const {
  if (home_switch_broken_) return false;
  const double a = position / steps_per_deg_ - params_.home_deg - home_offset_deg_;
  const double d = std::remainder(a, 360.0);
  return std::abs(d) <= params_.home_window_deg / 2;
}

void StageModel::setEnabled(bool enabled, Nanoseconds t) {
  if (enabled && !enabled_) {
    // Powering the driver resynchronises the motor and clears a stall fault.
    stalled_ = false;
    have_previous_ = false;
    if (fault_) setFault(false, t);
  }
  enabled_ = enabled;
}

void StageModel::setDirection(bool forward) {
  forward_ = forward;
}

void StageModel::setFault(bool fault, Nanoseconds t) {
  if (fault == fault_) return;
  fault_ = fault;
  fault_edges_.push({fault, t});
  ++edge_count_;
}

// The rotor follows a step when the step train is within the motor's torque:
//  - a pulse at or below the start/stop rate is always followed;
//  - faster pulses need speed <= max speed and |Δv/Δt| <= max acceleration,
//    with the speed of a pulse = 1 / (time since the previous pulse), signed
//    by the direction (a reversal at speed is a huge deceleration);
//  - after a lost step the rotor has stalled: it follows nothing until a pulse
//    slow enough to start from rest.
bool StageModel::followed(Nanoseconds t, int direction) {
  const double dt = have_previous_ ? seconds(t - previous_time_) : 1e9;
  const double start = params_.start_speed_deg_s * steps_per_deg_;
  const double speed = dt > 0 ? direction / dt : direction * 1e12;
  const double previous = previous_speed_;
  have_previous_ = true;
  previous_time_ = t;
  previous_speed_ = std::abs(speed) <= start ? 0.0 : speed;
  if (std::abs(speed) <= start) {
    stalled_ = false;
    return true;
  }
  if (stalled_) return false;
  const double max_speed = params_.max_speed_deg_s * steps_per_deg_;
  const double max_accel = params_.max_accel_deg_s2 * steps_per_deg_;
  // From a standstill the motor may jump to the start rate at once.
  const double base = previous == 0.0 ? direction * start : previous;
  if (std::abs(speed) > max_speed || std::abs(speed - base) / dt > max_accel) {
    stalled_ = true;
    return false;
  }
  return true;
}

void StageModel::stepPulse(Nanoseconds t) {
  if (!enabled_) {
    ++counters_.ignored;
    return;
  }
  ++counters_.pulses;
  if (scheduled_loss_ > 0 && counters_.pulses > scheduled_loss_after_) {
    inject_loss_ += scheduled_loss_;
    scheduled_loss_ = 0;
  }
  const int direction = forward_ ? 1 : -1;
  bool ok = followed(t, direction);
  if (ok && inject_loss_ > 0) {
    --inject_loss_;
    ok = false;
  }
  if (!ok) {
    ++counters_.lost;
    setFault(true, t);
    return;
  }
  position_ += direction;
  (direction > 0 ? counters_.forward : counters_.backward) += 1;
  // The stage follows the motor only once the play is taken up.
  const auto motor = static_cast<double>(position_);
  output_ = std::clamp(output_, motor - half_backlash_, motor + half_backlash_);
  history_.push({t, output_, std::abs(previous_speed_) / steps_per_deg_});
  const bool home = homeAt(output_);
  if (home != home_) {
    home_ = home;
    if (!home) drawHomeOffset();
    home_edges_.push({home, t});
    ++edge_count_;
  }
}

double StageModel::angleAt(Nanoseconds t) const {
  const std::uint64_t count = history_.count();
  const std::uint64_t oldest = history_.oldest();
  // Last sample at or before t (binary search; the history is time-ordered).
  std::uint64_t lo = oldest, hi = count;
  while (hi - lo > 1) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    if (history_.at(mid).time <= t) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  const Sample& s = history_.at(lo);
  double angle = s.position / steps_per_deg_;
  if (params_.settle_amplitude_deg > 0 && s.speed_deg_s > 0 && t > s.time) {
    const double dt = seconds(t - s.time);
    const double amp =
        params_.settle_amplitude_deg * std::min(1.0, s.speed_deg_s / params_.max_speed_deg_s);
    angle += amp * std::exp(-dt / (params_.settle_tau_ms * 1e-3)) *
             std::sin(2 * std::numbers::pi * params_.settle_freq_hz * dt);
  }
  return angle;
}

}  // namespace cylscan::sim
