// SPDX-License-Identifier: Apache-2.0
// Emits a StepSchedule on the step/dir (and trigger) lines against a Clock
// with absolute deadlines. The loop neither allocates nor locks (the buffer
// of edge times is sized before it starts), can be aborted from any thread,
// and records the lateness of every step and trigger edge.
//
// Late edges. Deadlines are absolute, so a rising edge a little late (by
// less than the schedule's lag tolerance: half a full step's worth of
// microsteps at the planned rate, which the rotor absorbs) changes nothing
// after it: the next edges keep their times and a long schedule does not
// drift. A later wake-up
// (the thread was preempted, the machine stalled) would otherwise emit the
// overdue steps back to back, a burst the motor cannot follow at speed. So
// the rest of the schedule is delayed instead (the run's `slip`): the steps
// after such an edge re-accelerate from the speed the motor actually has,
// with the schedule's start rate and acceleration, until they are back on the
// delayed plan (a "re-ramp"); triggers move with the steps. A pulse's falling
// edge follows its actual rising edge, so a late pulse is never short.
//
// It runs on the calling thread: the caller picks it (its own thread for a
// simple move, a RealtimeThread for a scan).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "drivers/clock.hpp"
#include "drivers/gpio.hpp"
#include "drivers/jitter_stats.hpp"
#include "drivers/motion_plan.hpp"

namespace cylscan::drivers {

// Asked after every step pulse whether to stop there (a seek that found its
// edge, a fault input). Must not allocate or block for long.
class StopCondition {
 public:
  virtual ~StopCondition() = default;
  virtual bool stopNow() = 0;
};

struct ExecutionResult {
  std::int64_t steps = 0;              // step pulses emitted (the move is steps × direction)
  std::int64_t triggers = 0;           // trigger pulses emitted
  bool aborted = false;                // abort() stopped it
  bool stopped = false;                // the stop condition stopped it
  std::chrono::nanoseconds origin{0};  // the schedule's zero (when dir was set)
  // How much later than planned the rest of the schedule ran after late
  // edges, and how many re-ramps that took (0 and 0 when nothing was late).
  std::chrono::nanoseconds slip{0};
  std::int64_t reramps = 0;
  bool complete(const StepSchedule& s) const {
    return steps == s.steps() && triggers == static_cast<std::int64_t>(s.triggers.size());
  }
};

class StepExecutor {
 public:
  // The lines must outlive the executor; `trigger` may be null when no
  // schedule run on it has triggers.
  StepExecutor(Clock& clock, OutputLine& step, OutputLine& dir, OutputLine* trigger = nullptr);

  // Sizes the edge-time buffer for schedules of up to `steps` steps (run()
  // does it too, before its loop).
  void reserve(std::int64_t steps);

  // Emits the schedule with its zero at `origin` (default: now). Leaves step
  // and trigger low. Returns early on abort() or when `stop` asks.
  ExecutionResult run(const StepSchedule& schedule, StopCondition* stop = nullptr,
                      std::optional<std::chrono::nanoseconds> origin = std::nullopt);
  // With another trigger line for this run (the cameras' trigger).
  ExecutionResult run(const StepSchedule& schedule, OutputLine& trigger,
                      StopCondition* stop = nullptr,
                      std::optional<std::chrono::nanoseconds> origin = std::nullopt);

  // From any thread: the running and every later run stop at the next edge
  // until rearm().
  void abort() noexcept { abort_.store(true, std::memory_order_release); }
  void rearm() noexcept { abort_.store(false, std::memory_order_release); }
  bool abortRequested() const noexcept { return abort_.load(std::memory_order_acquire); }

  // The actual time of each step's rising edge in the last run.
  std::span<const std::chrono::nanoseconds> stepTimes() const {
    return {step_times_.data(), static_cast<std::size_t>(last_steps_)};
  }

  // Lateness of the step and trigger rising edges over all runs (against the
  // deadline each was aimed at), and the re-ramps after late edges.
  const JitterStats& stepJitter() const { return step_jitter_; }
  const JitterStats& triggerJitter() const { return trigger_jitter_; }
  std::int64_t reramps() const noexcept { return reramps_; }
  std::chrono::nanoseconds slip() const noexcept { return slip_; }  // summed over runs
  void resetJitter() noexcept;

 private:
  ExecutionResult execute(const StepSchedule& schedule, OutputLine* trigger, StopCondition* stop,
                          std::optional<std::chrono::nanoseconds> origin);

  Clock& clock_;
  OutputLine& step_;
  OutputLine& dir_;
  OutputLine* trigger_;
  std::atomic<bool> abort_{false};
  std::vector<std::chrono::nanoseconds> step_times_;
  std::int64_t last_steps_ = 0;
  JitterStats step_jitter_;
  JitterStats trigger_jitter_;
  std::int64_t reramps_ = 0;
  std::chrono::nanoseconds slip_{0};
};

}  // namespace cylscan::drivers
