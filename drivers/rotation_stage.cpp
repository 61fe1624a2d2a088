// SPDX-License-Identifier: Apache-2.0
#include "drivers/rotation_stage.hpp"

#include <algorithm>
#include <array>
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

// `steps` brought into [-turn/2, turn/2) by whole turns.
std::int64_t nearestTurn(std::int64_t steps, std::int64_t turn) {
  std::int64_t r = ((steps % turn) + turn) % turn;
  if (2 * r >= turn) r -= turn;
  return r;
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

// Asked after every step: the fault input, and the home switch's active
// edges: a seek stops at the first; any other move notes them and goes on.
class RotationStage::Watch final : public StopCondition {
 public:
  Watch(InputLine* home, InputLine* fault, bool stop_at_home)
      : home_(home), fault_(fault), stop_at_home_(stop_at_home) {}
  bool stopNow() override {
    if (fault_ != nullptr && fault_->get()) {
      fault_seen = true;
      return true;
    }
    if (home_ == nullptr) return false;
    while (const std::optional<LineEvent> e = home_->waitEdge(Nanoseconds{0})) {
      const bool rising = e->edge == Edge::Rising;
      if (stop_at_home_) {
        if (!rising) continue;
        edge = e->timestamp;
        return true;
      }
      if (passed_count < passed.size()) passed[passed_count++] = {e->timestamp, rising};
    }
    return false;
  }
  bool fault_seen = false;
  std::optional<Nanoseconds> edge;
  // Edges passed on the way (no allocation: a move passes home a few times at most).
  struct Passed {
    Nanoseconds time{0};
    bool rising = false;
  };
  std::array<Passed, 2 * kMaxPassedEdges> passed{};
  std::size_t passed_count = 0;

 private:
  InputLine* home_;
  InputLine* fault_;
  bool stop_at_home_;
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
  if (!watch_home) drainHomeEdges();  // only this move's edges are its own
  Watch watch(lines_.home.get(), lines_.fault.get(), watch_home);
  Run run;
  // A reversal ends the pass in which the switch may still chatter.
  if (left_home_ && left_home_->direction != schedule.direction()) left_home_.reset();
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
  // The step that made an edge: the last one emitted at or before it.
  const auto times = executor_.stepTimes();
  const auto stepAt = [&](Nanoseconds t) {
    return static_cast<std::int64_t>(std::upper_bound(times.begin(), times.end(), t) -
                                     times.begin());
  };
  // A switch may chatter as the stage leaves it: an active edge soon after
  // leaving it in the same direction is not the stage meeting it again,
  // which takes a turn (or a reversal).
  const std::int64_t half_turn = std::llround(180.0 * config_.stepsPerDeg());
  for (std::size_t i = 0; i < watch.passed_count; ++i) {
    const std::int64_t k = stepAt(watch.passed[i].time);
    if (k == 0) continue;  // it came before the move
    const std::int64_t at = before + d * k;
    if (!watch.passed[i].rising) {
      left_home_ = LeftHome{at, d};
      continue;
    }
    if (left_home_ && left_home_->direction == d && std::abs(at - left_home_->position) < half_turn)
      continue;
    if (run.passed_count < run.passed.size()) run.passed[run.passed_count++] = at;
  }
  if (homed_) checkPassedEdges(run, d);
  if (!watch.edge) return run;
  run.edge_position = before + d * stepAt(*watch.edge);
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
    Watch fault_only(nullptr, lines_.fault.get(), false);
    const ExecutionResult r = executor_.run(ramp, &fault_only, times[last]);
    position_ += d * r.steps;
    noteLastStep(r.steps);
    if (r.aborted) fail("move aborted while ramping down");
    if (fault_only.fault_seen) fail("stage fault input active while ramping down");
  }
  return run;
}

void RotationStage::checkPassedEdges(const Run& run, int direction) {
  const std::optional<std::int64_t>& edge = edgeFor(direction);
  if (!edge) return;
  const std::optional<std::int64_t> turn = config_.stepsPerTurn();
  for (std::size_t i = 0; i < run.passed_count; ++i) {
    const std::int64_t found = run.passed[i];
    const std::int64_t off = turn ? nearestTurn(found - *edge, *turn) : found - *edge;
    const std::int64_t expected = found - off;
    if (std::abs(off) > config_.step_check_tolerance_steps) {
      fail("lost " + std::to_string(std::abs(off)) + " steps: the home edge is at step " +
           std::to_string(found) + " as the stage passes it, the executed count expects " +
           std::to_string(expected) + " (tolerance " +
           std::to_string(config_.step_check_tolerance_steps) + ")");
    }
    last_passed_check_ = StepCheck{expected, found, true};
    ++passed_checks_;
  }
}

RotationStage::Run RotationStage::move(std::int64_t steps, double speed_deg_s) {
  requireEnabled("a move");
  checkFault("before a move");
  Run run = execute(planMove(config_, steps, speed_deg_s), false, nullptr);
  checkFault("after a move");
  return run;
}

std::int64_t RotationStage::moveBySteps(std::int64_t steps) {
  move(steps, config_.max_speed_deg_s);
  return position_;
}

std::int64_t RotationStage::moveToStep(std::int64_t target) {
  move(target - position_, config_.max_speed_deg_s);
  return position_;
}

std::int64_t RotationStage::turnTo(std::int64_t target, int direction) {
  const std::optional<std::int64_t> turn = config_.stepsPerTurn();
  if (!turn)
    throw std::logic_error("rotation stage: turnTo() needs a whole number of steps a turn");
  if (direction != 1 && direction != -1) {
    throw std::invalid_argument("rotation stage: turnTo() direction must be +1 or -1");
  }
  std::int64_t steps = ((target - position_) % *turn + *turn) % *turn;  // [0, turn)
  if (direction < 0 && steps != 0) steps -= *turn;
  move(steps, config_.max_speed_deg_s);
  // The same place, counted within the turn the plan uses.
  if (left_home_) left_home_->position += target - position_;
  position_ = target;
  return position_;
}

bool RotationStage::passesCheckedEdge(std::int64_t from, std::int64_t steps) const {
  if (steps == 0) return false;
  const int d = steps > 0 ? 1 : -1;
  const std::optional<std::int64_t>& edge = edgeFor(d);
  if (!edge) return false;
  // The edge must lie well inside the move, so that a count off by the
  // tolerance still meets it.
  const std::int64_t margin = config_.step_check_tolerance_steps + 1;
  const std::int64_t lo = std::min(from, from + steps) + margin;
  const std::int64_t hi = std::max(from, from + steps) - margin;
  if (lo > hi) return false;
  const std::optional<std::int64_t> turn = config_.stepsPerTurn();
  if (!turn) return *edge >= lo && *edge <= hi;
  const std::int64_t first = lo + ((*edge - lo) % *turn + *turn) % *turn;  // ≥ lo, ≡ edge
  return first <= hi;
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
  edge_ = {};
  left_home_.reset();
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
  // Backing off passes the switch's other edge (the one a move away from
  // home meets) when the seek's ramp down went beyond the window.
  const Run back =
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
  const std::int64_t rebase = degToSteps(config_.home_offset_deg) - *approach.edge_position;
  position_ += rebase;
  edgeFor(d) = degToSteps(config_.home_offset_deg);
  if (back.passed_count > 0) edgeFor(-d) = back.passed[0] + rebase;
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
  check.passed = false;
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
