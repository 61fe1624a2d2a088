#include "drivers/step_executor.hpp"

#include <limits>
#include <stdexcept>

namespace cylscan::drivers {

namespace {

using Nanoseconds = std::chrono::nanoseconds;
constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::max();

// One pulse train (steps or triggers): the next edge and whether it rises.
struct Train {
  std::int64_t index = 0;  // pulses emitted
  std::int64_t count = 0;
  bool high = false;
  std::int64_t high_ns = 0;
  template <typename TimeOf>
  std::int64_t next(TimeOf time_of) const {
    if (high) return time_of(index) + high_ns;
    return index < count ? time_of(index) : kNever;
  }
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
  auto step_time = [steps](std::int64_t i) { return steps[i]; };
  auto trigger_time = [triggers](std::int64_t i) { return triggers[i].time_ns; };

  dir_.set(schedule.forward);
  for (;;) {
    const std::int64_t next_step = s.next(step_time);
    const std::int64_t next_trigger = t.next(trigger_time);
    if (next_step == kNever && next_trigger == kNever) break;
    // Equal times: the step first, so a trigger follows the step it counts.
    const bool is_step = next_step <= next_trigger;
    Train& train = is_step ? s : t;
    const std::int64_t deadline = t0 + (is_step ? next_step : next_trigger);
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
      if (is_step) step_times_[static_cast<std::size_t>(s.index)] = now;
      train.high = true;
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
  last_steps_ = s.index;
  return result;
}

}  // namespace cylscan::drivers
