// SPDX-License-Identifier: Apache-2.0
#include "drivers/rotation_stage.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace cylscan::drivers {

namespace {

using Nanoseconds = std::chrono::nanoseconds;

std::string degrees(double deg) {
  char text[32];
  std::snprintf(text, sizeof text, "%g°", deg);
  return text;
}

void requireLine(bool present, const char* role) {
  if (!present) throw std::invalid_argument(std::string("rotation stage: no ") + role + " line");
}

}  // namespace

StageLines requestStageLines(GpioBackend& gpio, const StageLineSpecs& specs) {
  StageLines lines;
  lines.enable = gpio.requestOutput(specs.enable, false);
  lines.step = gpio.requestOutput(specs.step, false);
  lines.dir = gpio.requestOutput(specs.dir, false);
  lines.home = gpio.requestInput(specs.home);
  if (specs.fault) lines.fault = gpio.requestInput(*specs.fault);
  return lines;
}

// Asked after every step: the fault input, and (when watched) the first
// active edge of the home switch.
class RotationStage::Watch final : public StopCondition {
 public:
  Watch(InputLine* home, InputLine* fault) : home_(home), fault_(fault) {}
  bool stopNow() override {
    if (fault_ != nullptr && fault_->get()) {
      fault_seen = true;
      return true;
    }
    if (home_ == nullptr) return false;
    while (const std::optional<LineEvent> e = home_->waitEdge(Nanoseconds{0})) {
      if (e->edge == Edge::Rising) {
        edge = e->timestamp;
        return true;
      }
    }
    return false;
  }
  bool fault_seen = false;
  std::optional<Nanoseconds> edge;

 private:
  InputLine* home_;
  InputLine* fault_;
};

RotationStage::RotationStage(StageConfig config, Clock& clock, StageLines lines)
    : config_((validate(config), config)),
      clock_(clock),
      lines_(std::move(lines)),
      executor_(clock, (requireLine(lines_.step != nullptr, "step"), *lines_.step),
                (requireLine(lines_.dir != nullptr, "dir"), *lines_.dir)) {
  requireLine(lines_.enable != nullptr, "enable");
  requireLine(lines_.home != nullptr, "home");
  lines_.enable->set(false);
  lines_.step->set(false);
}

RotationStage::RotationStage(StageConfig config, Clock& clock, GpioBackend& gpio,
                             const StageLineSpecs& specs)
    : RotationStage(config, clock, requestStageLines(gpio, specs)) {}

RotationStage::~RotationStage() {
  try {
    disable();
  } catch (...) {  // nothing can be reported from a destructor; the line stays as it was
  }
}

void RotationStage::enable() {
  lines_.enable->set(true);
  enabled_ = true;
  executor_.rearm();
  clock_.sleepUntil(clock_.now() + Nanoseconds{std::llround(config_.enable_settle_ms * 1e6)});
}

void RotationStage::disable() {
  enabled_ = false;
  lines_.step->set(false);
  lines_.enable->set(false);
}

void RotationStage::fail(const std::string& message) {
  // A move that ended in a fault or an abort may have lost steps: the
  // position is no longer known, so the next user homes again.
  homed_ = false;
  std::string text = "rotation stage: " + message;
  try {
    disable();
    text += " (stage disabled)";
  } catch (const std::exception& e) {
    text += std::string(" (and disabling it failed: ") + e.what() + ")";
  }
  throw StageError(text);
}

void RotationStage::requireEnabled(const char* what) {
  if (!enabled_) throw StageError(std::string("rotation stage: ") + what + " needs enable()");
}

void RotationStage::checkFault(const char* when) {
  if (lines_.fault && lines_.fault->get()) fail(std::string("stage fault input active ") + when);
}

std::int64_t RotationStage::degToSteps(double deg) const {
  return std::llround(deg * config_.stepsPerDeg());
}

void RotationStage::drainHomeEdges() {
  while (lines_.home->waitEdge(Nanoseconds{0})) {
  }
}

Nanoseconds RotationStage::originFor(const StepSchedule& schedule) const {
  const Nanoseconds now = clock_.now();
  if (!last_step_ || schedule.step_ns.empty()) return now;
  const Nanoseconds rest{std::llround(1e9 / (config_.start_speed_deg_s * config_.stepsPerDeg()))};
  return std::max(now, *last_step_ + rest - Nanoseconds{schedule.step_ns.front()});
}

void RotationStage::noteLastStep(std::int64_t steps) {
  if (steps > 0) last_step_ = executor_.stepTimes()[static_cast<std::size_t>(steps - 1)];
}

RotationStage::Run RotationStage::execute(const StepSchedule& schedule, bool watch_home,
                                          OutputLine* trigger) {
  Watch watch(watch_home ? lines_.home.get() : nullptr, lines_.fault.get());
  Run run;
  const Nanoseconds origin = originFor(schedule);
  run.result = trigger ? executor_.run(schedule, *trigger, &watch, origin)
                       : executor_.run(schedule, &watch, origin);
  noteLastStep(run.result.steps);
  const std::int64_t before = position_;
  const int d = schedule.direction();
  position_ += d * run.result.steps;
  if (run.result.aborted) {
    fail("move aborted after " + std::to_string(run.result.steps) + " of " +
         std::to_string(schedule.steps()) + " steps");
  }
  if (watch.fault_seen) {
    fail("stage fault input active during a move (after " + std::to_string(run.result.steps) +
         " of " + std::to_string(schedule.steps()) + " steps)");
  }
  if (!watch.edge) return run;
  // The step that made the edge: the last one emitted at or before it.
  const auto times = executor_.stepTimes();
  const auto k = std::upper_bound(times.begin(), times.end(), *watch.edge) - times.begin();
  run.edge_position = before + d * static_cast<std::int64_t>(k);
  run.edge_time = *watch.edge;
  // Stopped at speed: ramp down instead of stopping dead, from the last
  // step as it went out (after a late edge the motor may be slower than
  // planned, never faster).
  const std::int64_t n = run.result.steps;
  if (run.result.stopped && n >= 2) {
    const auto last = static_cast<std::size_t>(n - 1);
    const double planned =
        1e9 / static_cast<double>(schedule.step_ns[last] - schedule.step_ns[last - 1]);
    const auto actual_gap = static_cast<double>((times[last] - times[last - 1]).count());
    const double speed = actual_gap > 0 ? std::min(planned, 1e9 / actual_gap) : planned;
    const StepSchedule ramp = planStop(config_, schedule.forward, speed);
    Watch fault_only(nullptr, lines_.fault.get());
    const ExecutionResult r = executor_.run(ramp, &fault_only, times[last]);
    position_ += d * r.steps;
    noteLastStep(r.steps);
    if (r.aborted) fail("move aborted while ramping down");
    if (fault_only.fault_seen) fail("stage fault input active while ramping down");
  }
  return run;
}

std::int64_t RotationStage::move(std::int64_t steps, double speed_deg_s) {
  requireEnabled("a move");
  checkFault("before a move");
  execute(planMove(config_, steps, speed_deg_s), false, nullptr);
  checkFault("after a move");
  return position_;
}

std::int64_t RotationStage::moveBySteps(std::int64_t steps) {
  return move(steps, config_.max_speed_deg_s);
}

std::int64_t RotationStage::moveToStep(std::int64_t target) {
  return move(target - position_, config_.max_speed_deg_s);
}

std::int64_t RotationStage::moveTo(double angle_deg) {
  if (!homed_) throw StageError("rotation stage: moveTo(angle) needs home() first");
  if (!std::isfinite(angle_deg)) throw std::invalid_argument("rotation stage: angle not finite");
  return moveToStep(degToSteps(angle_deg));
}

RotationStage::Run RotationStage::seekEdge(std::int64_t steps, double speed_deg_s) {
  drainHomeEdges();
  return execute(planMove(config_, steps, speed_deg_s), true, nullptr);
}

HomeResult RotationStage::home() {
  requireEnabled("home()");
  checkFault("before homing");
  homed_ = false;
  const int d = config_.home_direction;
  const std::int64_t backoff = degToSteps(config_.home_backoff_deg);
  const std::string backoff_text = degrees(config_.home_backoff_deg);
  if (lines_.home->get()) {  // on the switch: leave it first
    move(-d * backoff, config_.home_seek_speed_deg_s);
    if (lines_.home->get()) {
      fail("home switch still active " + backoff_text +
           " away from where it was: stuck, or its polarity is wrong");
    }
  }
  const std::int64_t seek_start = position_;
  const Run seek =
      seekEdge(d * degToSteps(config_.home_max_travel_deg), config_.home_seek_speed_deg_s);
  if (!seek.edge_position) {
    fail("home switch never fired within " + degrees(config_.home_max_travel_deg) +
         " of travel (home_max_travel_deg)");
  }
  HomeResult result;
  result.seek_steps = d * (*seek.edge_position - seek_start);
  move(*seek.edge_position - d * backoff - position_, config_.home_seek_speed_deg_s);
  if (lines_.home->get()) {
    fail("home switch still active " + backoff_text + " back from its edge: stuck, or its " +
         "polarity is wrong");
  }
  const Run approach = seekEdge(std::int64_t{2} * d * backoff, config_.home_approach_speed_deg_s);
  if (!approach.edge_position) {
    fail("home edge not found again on the slow approach (within " +
         degrees(2 * config_.home_backoff_deg) + ")");
  }
  position_ += degToSteps(config_.home_offset_deg) - *approach.edge_position;
  homed_ = true;
  result.edge_time = approach.edge_time;
  return result;
}

StepCheck RotationStage::verifyStepCount() {
  requireEnabled("verifyStepCount()");
  if (!homed_) throw StageError("rotation stage: verifyStepCount() needs home() first");
  const int d = config_.home_direction;
  const std::int64_t backoff = degToSteps(config_.home_backoff_deg);
  StepCheck check;
  check.expected_edge = degToSteps(config_.home_offset_deg);
  moveToStep(check.expected_edge - d * backoff);
  if (lines_.home->get()) {
    fail("lost steps: the home switch is active where the executed count puts the stage " +
         degrees(config_.home_backoff_deg) + " from its edge");
  }
  const Run r = seekEdge(std::int64_t{2} * d * backoff, config_.home_approach_speed_deg_s);
  if (!r.edge_position) {
    fail("lost steps: the home edge is not within " + degrees(config_.home_backoff_deg) +
         " of where the executed count puts it");
  }
  check.found_edge = *r.edge_position;
  const std::int64_t lost = std::abs(check.lostSteps());
  if (lost > config_.step_check_tolerance_steps) {
    fail("lost " + std::to_string(lost) + " steps: the home edge is at step " +
         std::to_string(check.found_edge) + ", the executed count expects " +
         std::to_string(check.expected_edge) + " (tolerance " +
         std::to_string(config_.step_check_tolerance_steps) + ")");
  }
  return check;
}

PreparedSweep RotationStage::prepareSweep(std::int64_t range_start, const SweepRequest& request) {
  requireEnabled("prepareSweep()");
  PreparedSweep sweep;
  sweep.plan = planSweep(config_, request);
  sweep.start_position = range_start - request.direction * sweep.plan.run_up_steps;
  for (const TriggerPulse& t : sweep.plan.schedule.triggers) {
    const std::int64_t p = sweep.start_position + request.direction * t.step_count;
    sweep.trigger_positions.push_back(p);
    sweep.trigger_angles_deg.push_back(stepsToDeg(p));
  }
  executor_.reserve(sweep.plan.schedule.steps());
  moveToStep(sweep.start_position);
  return sweep;
}

void RotationStage::runSweep(const PreparedSweep& sweep, OutputLine& trigger) {
  requireEnabled("runSweep()");
  if (position_ != sweep.start_position) {
    fail("runSweep(): the stage is at step " + std::to_string(position_) +
         ", the sweep starts at " + std::to_string(sweep.start_position));
  }
  checkFault("before a sweep");
  const StepSchedule& s = sweep.plan.schedule;
  const Run r = execute(s, false, &trigger);
  if (!r.result.complete(s)) {
    fail("sweep incomplete: " + std::to_string(r.result.steps) + " of " +
         std::to_string(s.steps()) + " steps, " + std::to_string(r.result.triggers) + " of " +
         std::to_string(s.triggers.size()) + " triggers");
  }
  checkFault("after a sweep");
}

}  // namespace cylscan::drivers
