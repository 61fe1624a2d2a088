// SPDX-License-Identifier: Apache-2.0
#include "drivers/step_executor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace cylscan::drivers {

namespace {

using Nanoseconds = std::chrono::nanoseconds;
constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::max();

// One pulse train (steps or triggers): how many went out, and the rising
// edge of the one that is high.
struct Train {
  std::int64_t index = 0;  // pulses emitted
  std::int64_t count = 0;
  bool high = false;
  std::int64_t high_ns = 0;
  std::int64_t rose_at = 0;  // absolute time of the high pulse's rising edge
};

}  // namespace

StepExecutor::StepExecutor(Clock& clock, OutputLine& step, OutputLine& dir, OutputLine* trigger)
    : clock_(clock), step_(step), dir_(dir), trigger_(trigger) {}

void StepExecutor::reserve(std::int64_t steps) {
  if (steps > static_cast<std::int64_t>(step_times_.size())) {
    step_times_.resize(static_cast<std::size_t>(steps));
  }
}

void StepExecutor::resetJitter() noexcept {
  step_jitter_.reset();
  trigger_jitter_.reset();
  reramps_ = 0;
  slip_ = Nanoseconds{0};
}

ExecutionResult StepExecutor::run(const StepSchedule& schedule, StopCondition* stop,
                                  std::optional<Nanoseconds> origin) {
  return execute(schedule, trigger_, stop, origin);
}

ExecutionResult StepExecutor::run(const StepSchedule& schedule, OutputLine& trigger,
                                  StopCondition* stop, std::optional<Nanoseconds> origin) {
  return execute(schedule, &trigger, stop, origin);
}

ExecutionResult StepExecutor::execute(const StepSchedule& schedule, OutputLine* trigger,
                                      StopCondition* stop, std::optional<Nanoseconds> origin) {
  if (!schedule.triggers.empty() && trigger == nullptr) {
    throw std::invalid_argument("step executor: the schedule has triggers but no trigger line");
  }
  reserve(schedule.steps());
  last_steps_ = 0;
  ExecutionResult result;
  result.origin = origin ? *origin : clock_.now();
  const std::int64_t t0 = result.origin.count();

  // From here on: no allocation, no lock (the clock's sleep aside).
  const std::int64_t* steps = schedule.step_ns.data();
  const TriggerPulse* triggers = schedule.triggers.data();
  Train s{0, schedule.steps(), false, schedule.step_high_ns};
  Train t{0, static_cast<std::int64_t>(schedule.triggers.size()), false, schedule.trigger_high_ns};
  const bool can_ramp = schedule.accel_steps_s2 > 0;
  std::int64_t slip = 0;              // the delay of the rest of the schedule
  bool recovering = false;            // re-ramping after a late edge
  double ramp_speed = 0;              // while recovering: the last step's commanded speed, steps/s
  std::int64_t last_rise = 0;         // the last step's rising edge (absolute)
  std::int64_t prev_rise = 0;         // the one before it
  std::int64_t last_aim = 0;          // the deadline the last step was aimed at
  auto allowed = [&](double speed) {  // the next step's speed, steps/s
    const double base = std::max(speed, schedule.start_rate_steps_s);
    return (base + std::sqrt(base * base + 4 * schedule.accel_steps_s2)) / 2;
  };

  // The next step's rising edge: its planned time plus the slip, or later
  // when an edge before it was late (see the header). Decided once per step.
  // The re-ramp's speeds are commanded ones: the jitter of the edges that
  // follow a late one is absorbed as on plan, never fed back into the ramp.
  std::int64_t decided_for = -1;
  std::int64_t decided = 0;
  auto step_deadline = [&]() {
    const std::int64_t i = s.index;
    if (i == decided_for) return decided;
    decided_for = i;
    decided = t0 + slip + steps[i];
    if (i == 0) return decided;
    const std::int64_t planned_gap = steps[i] - steps[i - 1];
    // While recovering, the ramp's next speed (computed once: this is the
    // real-time loop) sets the interval this step is meant to follow.
    const double next_ramp = recovering ? allowed(ramp_speed) : 0.0;
    const std::int64_t intended_gap =
        recovering ? static_cast<std::int64_t>(std::ceil(1e9 / next_ramp)) : planned_gap;
    const bool late_edge = static_cast<double>(last_rise - last_aim) >
                           schedule.lag_tolerance_steps * static_cast<double>(intended_gap);
    std::int64_t earliest = 0;
    if (late_edge && !can_ramp) {
      earliest = last_rise + planned_gap;
      ++result.reramps;
    } else if (late_edge) {
      // The motor's speed is the last actual interval's (the pause in it).
      const double measured =
          i >= 2 && last_rise > prev_rise ? 1e9 / static_cast<double>(last_rise - prev_rise) : 0.0;
      if (!recovering) ++result.reramps;
      recovering = true;
      ramp_speed = allowed(measured);
      earliest = last_rise + static_cast<std::int64_t>(std::ceil(1e9 / ramp_speed));
    } else if (recovering) {
      ramp_speed = next_ramp;
      earliest = last_aim + intended_gap;
    } else {
      return decided;
    }
    if (earliest <= decided) {
      recovering = false;
      return decided;
    }
    slip += earliest - decided;
    decided = earliest;
    return decided;
  };

  dir_.set(schedule.forward);
  for (;;) {
    const std::int64_t next_step =
        s.high ? s.rose_at + s.high_ns : (s.index < s.count ? step_deadline() : kNever);
    const std::int64_t next_trigger =
        t.high ? t.rose_at + t.high_ns
               : (t.index < t.count ? t0 + slip + triggers[t.index].time_ns : kNever);
    if (next_step == kNever && next_trigger == kNever) break;
    // Equal times: the step first, so a trigger follows the step it counts.
    const bool is_step = next_step <= next_trigger;
    Train& train = is_step ? s : t;
    const std::int64_t deadline = is_step ? next_step : next_trigger;
    if (!train.high && abort_.load(std::memory_order_acquire)) {
      result.aborted = true;
      break;
    }
    clock_.sleepUntil(Nanoseconds{deadline});
    OutputLine& line = is_step ? step_ : *trigger;
    if (!train.high) {
      line.set(true);
      const Nanoseconds now = clock_.now();
      (is_step ? step_jitter_ : trigger_jitter_).record(now - Nanoseconds{deadline});
      train.high = true;
      train.rose_at = now.count();
      if (is_step) {
        step_times_[static_cast<std::size_t>(s.index)] = now;
        prev_rise = last_rise;
        last_rise = now.count();
        last_aim = deadline;
      }
      continue;
    }
    line.set(false);
    train.high = false;
    ++train.index;
    if (is_step && stop != nullptr && stop->stopNow()) {
      result.stopped = true;
      break;
    }
  }
  if (s.high) {  // never leave a line high
    step_.set(false);
    ++s.index;
  }
  if (t.high) {
    trigger->set(false);
    ++t.index;
  }
  result.steps = s.index;
  result.triggers = t.index;
  result.slip = Nanoseconds{slip};
  reramps_ += result.reramps;
  slip_ += result.slip;
  last_steps_ = s.index;
  return result;
}

}  // namespace cylscan::drivers
