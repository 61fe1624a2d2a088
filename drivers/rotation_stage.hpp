// SPDX-License-Identifier: Apache-2.0
// The rotation stage as the firmware drives it: enable, homing, moves and
// continuous sweeps planned by motion_plan and emitted by a StepExecutor on
// the calling thread, the executed position in steps, a step-count check
// against the home switch, and the stage fault input. Any failure or abort
// disables the stage before the StageError leaves; so does destruction.
//
// One thread drives it at a time; abort() and the jitter figures are for any
// thread. Which thread runs a move is the caller's choice: prepareSweep() on
// an ordinary thread, runSweep() (no allocation) on a RealtimeThread.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <vector>

#include "drivers/clock.hpp"
#include "drivers/gpio.hpp"
#include "drivers/motion_plan.hpp"
#include "drivers/stage_config.hpp"
#include "drivers/step_executor.hpp"

namespace cylscan::drivers {

class StageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct StageLines {
  std::unique_ptr<OutputLine> step, dir, enable;
  std::unique_ptr<InputLine> home;
  std::unique_ptr<InputLine> fault;  // optional
};

struct StageLineSpecs {
  LineSpec step, dir, enable, home;
  std::optional<LineSpec> fault;
};

// Requests the lines (outputs inactive: stage disabled); GpioError on failure.
StageLines requestStageLines(GpioBackend& gpio, const StageLineSpecs& specs);

struct HomeResult {
  std::int64_t seek_steps = 0;            // steps of the seek until the edge
  std::chrono::nanoseconds edge_time{0};  // timestamp of the slow approach's home edge
};

struct StepCheck {
  std::int64_t expected_edge = 0;  // where the count puts the home edge (steps)
  std::int64_t found_edge = 0;     // where it was found, in the same count
  bool passed = false;             // found passing it on the way, not by a seek
  std::int64_t lostSteps() const { return found_edge - expected_edge; }
};

// Home edges a single move can note as it passes them.
inline constexpr std::size_t kMaxPassedEdges = 8;

// A sweep ready to run: planned, the stage at its start.
struct PreparedSweep {
  SweepPlan plan;
  std::int64_t start_position = 0;              // executed steps when it starts
  std::vector<std::int64_t> trigger_positions;  // the stage position at each trigger (steps)
  std::vector<double> trigger_angles_deg;       // the same in degrees
};

class RotationStage {
 public:
  RotationStage(StageConfig config, Clock& clock, StageLines lines);
  RotationStage(StageConfig config, Clock& clock, GpioBackend& gpio, const StageLineSpecs& specs);
  ~RotationStage();  // disables the stage
  RotationStage(const RotationStage&) = delete;
  RotationStage& operator=(const RotationStage&) = delete;

  const StageConfig& config() const { return config_; }

  // enable() powers the driver, waits enable_settle_ms and re-arms after an
  // abort. disable() drives step low and enable inactive.
  void enable();
  void disable();
  bool enabled() const { return enabled_; }

  // Seek the home edge in home_direction at the seek speed (leaving the
  // switch first if on it), back off, approach slowly, and set the position
  // of the edge step to home_offset_deg. StageError "home switch never
  // fired" when no edge comes within home_max_travel_deg.
  HomeResult home();
  bool homed() const { return homed_; }

  // Moves with the configured trapezoid; the executed position in steps.
  // Every move notes the home edges it passes; once homed, each is compared
  // with where the count puts that edge for the direction of the move (the
  // switch is a window: its edge moving up is not its edge moving down, and
  // backlash differs by direction), and StageError "lost N steps" beyond
  // step_check_tolerance_steps. The edge of the homing direction is known
  // from homing; the other one from homing's back-off, when that passes it.
  std::int64_t moveBySteps(std::int64_t steps);
  std::int64_t moveToStep(std::int64_t target);
  // With a whole number of steps per turn: moves `direction` (+1 or -1) to
  // the nearest position that is `target` modulo a turn, and counts it as
  // `target` (std::logic_error without one).
  std::int64_t turnTo(std::int64_t target, int direction);
  // Whether a move of `steps` from `from` would pass a home edge that checks
  // the count (one whose position is known for that direction).
  bool passesCheckedEdge(std::int64_t from, std::int64_t steps) const;
  // The last check made on the way, and how many since resetPassedChecks().
  const std::optional<StepCheck>& lastPassedCheck() const { return last_passed_check_; }
  int passedChecks() const { return passed_checks_; }
  void resetPassedChecks() noexcept {
    last_passed_check_.reset();
    passed_checks_ = 0;
  }
  std::int64_t moveTo(double angle_deg);  // the nearest step; needs home()

  // Executed position: steps emitted × direction since homing (or power-up).
  std::int64_t position() const { return position_; }
  double angleDeg() const { return static_cast<double>(position_) / config_.stepsPerDeg(); }
  double stepsToDeg(std::int64_t steps) const {
    return static_cast<double>(steps) / config_.stepsPerDeg();
  }

  // Continuous mode: plans a sweep whose constant-speed range starts at
  // `range_start` (steps) and moves the stage to the run-up point.
  PreparedSweep prepareSweep(std::int64_t range_start, const SweepRequest& request);
  // Emits it with the triggers on `trigger` (no allocation unless it fails).
  // Afterwards position() is the end of the sweep; StageError when it did
  // not run completely.
  void runSweep(const PreparedSweep& sweep, OutputLine& trigger);

  // Re-seeks the home edge from the side the homing approached it and
  // compares where it is found with where the executed count says it is;
  // StageError "lost N steps" beyond step_check_tolerance_steps.
  StepCheck verifyStepCount();

  // From any thread: the running move stops at its next edge and fails; so
  // does every move until enable().
  void abort() noexcept { executor_.abort(); }

  const StepExecutor& executor() const { return executor_; }
  // Between moves (no thread emitting): the executor's lateness, re-ramp and
  // slip figures start again, so a scan reports its own.
  void resetTimingStats() noexcept { executor_.resetJitter(); }

 private:
  class Watch;
  struct Run {
    ExecutionResult result;
    std::optional<std::int64_t> edge_position;  // of the home edge, when watched for and seen
    std::chrono::nanoseconds edge_time{0};
    std::array<std::int64_t, kMaxPassedEdges> passed{};  // edges passed on the way (steps)
    std::size_t passed_count = 0;
  };
  void checkPassedEdges(const Run& run, int direction);
  std::optional<std::int64_t>& edgeFor(int direction) { return edge_[direction > 0 ? 1 : 0]; }
  const std::optional<std::int64_t>& edgeFor(int direction) const {
    return edge_[direction > 0 ? 1 : 0];
  }
  Run execute(const StepSchedule& schedule, bool watch_home, OutputLine* trigger);
  std::chrono::nanoseconds originFor(const StepSchedule& schedule) const;
  void noteLastStep(std::int64_t steps);
  Run seekEdge(std::int64_t steps, double speed_deg_s);
  Run move(std::int64_t steps, double speed_deg_s);
  void drainHomeEdges();
  void requireEnabled(const char* what);
  void checkFault(const char* when);
  [[noreturn]] void fail(const std::string& message);
  std::int64_t degToSteps(double deg) const;

  StageConfig config_;
  Clock& clock_;
  StageLines lines_;
  StepExecutor executor_;
  bool enabled_ = false;
  bool homed_ = false;
  std::int64_t position_ = 0;
  // Where the count puts the home edge met moving down [0] and up [1]
  // (modulo a turn when it is whole); set by homing.
  std::array<std::optional<std::int64_t>, 2> edge_;
  std::optional<StepCheck> last_passed_check_;
  int passed_checks_ = 0;
  // Where and which way a move last saw the switch go inactive.
  struct LeftHome {
    std::int64_t position = 0;
    int direction = 0;
  };
  std::optional<LeftHome> left_home_;
  // The last step emitted: the next move's first step comes no sooner than
  // one start-speed interval after it (the motor starts from rest).
  std::optional<std::chrono::nanoseconds> last_step_;
};

}  // namespace cylscan::drivers
