// SPDX-License-Identifier: Apache-2.0
// The executor against the virtual head: the stage executes exactly the
// planned steps, edges land on their deadlines in virtual time, the lines
// are left low, abort and stop conditions end a run at a step boundary, and
// a late wake-up at speed re-ramps instead of bursting the overdue steps.
#include <gtest/gtest.h>

#include <iostream>
#include <vector>

#include "drivers/step_executor.hpp"
#include "drivers_test_support.hpp"

namespace cylscan::drivers {
namespace {

using namespace std::chrono_literals;

class ExecutorTest : public ::testing::Test {
 protected:
  ExecutorTest()
      : head(test::smallHead(), test::planeScene()),
        step(head.gpio().requestOutput(test::spec("step"), false)),
        dir(head.gpio().requestOutput(test::spec("dir"), false)),
        enable(head.gpio().requestOutput(test::spec("enable"), true)),
        executor(head.clock(), *step, *dir) {}
  sim::VirtualHead head;
  std::unique_ptr<OutputLine> step, dir, enable;
  StepExecutor executor;
  StageConfig config = test::stageFor(test::smallHead());
};

TEST_F(ExecutorTest, TheStageExecutesThePlanOnItsDeadlines) {
  const std::int64_t start = head.stage().position();
  const StepSchedule forward = planMove(config, 4000);
  const ExecutionResult r = executor.run(forward);
  EXPECT_TRUE(r.complete(forward));
  EXPECT_EQ(head.stage().position(), start + 4000);
  EXPECT_EQ(head.stage().counters().lost, 0u);
  ASSERT_EQ(executor.stepTimes().size(), 4000u);
  for (std::size_t i = 0; i < 4000; ++i) {
    ASSERT_EQ(executor.stepTimes()[i], r.origin + std::chrono::nanoseconds{forward.step_ns[i]});
  }
  EXPECT_EQ(head.clock().now(), r.origin + std::chrono::nanoseconds{forward.durationNs()});
  // The motor starts from rest: not sooner than one start-speed interval.
  head.clock().sleepUntil(head.clock().now() + 10ms);
  const StepSchedule back = planMove(config, -1500);
  EXPECT_TRUE(executor.run(back).complete(back));
  EXPECT_EQ(head.stage().position(), start + 2500);
  EXPECT_EQ(head.stage().counters().backward, 1500u);
  EXPECT_EQ(head.stage().counters().lost, 0u);
  // In virtual time every edge is exactly on its deadline.
  const auto j = executor.stepJitter().snapshot();
  EXPECT_EQ(j.count, 5500u);
  EXPECT_EQ(j.max, 0ns);
  EXPECT_EQ(executor.triggerJitter().snapshot().count, 0u);
}

TEST_F(ExecutorTest, TriggersNeedALine) {
  SweepRequest r;
  r.speed_deg_s = 5;
  r.range_steps = 10;
  r.trigger_offsets = {0};
  EXPECT_THROW(executor.run(planSweep(config, r).schedule), std::invalid_argument);
}

class StopAfter final : public StopCondition {
 public:
  StopAfter(int n, StepExecutor* abort_it) : n_(n), abort_(abort_it) {}
  bool stopNow() override {
    if (--n_ > 0) return false;
    if (abort_ == nullptr) return true;
    abort_->abort();  // from "another party": the next rising edge does not come
    return false;
  }

 private:
  int n_;
  StepExecutor* abort_;
};

TEST_F(ExecutorTest, AStopConditionEndsTheRunAfterAStep) {
  const std::int64_t start = head.stage().position();
  StopAfter stop(37, nullptr);
  const ExecutionResult r = executor.run(planMove(config, 1000), &stop);
  EXPECT_TRUE(r.stopped);
  EXPECT_FALSE(r.aborted);
  EXPECT_EQ(r.steps, 37);
  EXPECT_EQ(head.stage().position(), start + 37);
  EXPECT_EQ(executor.stepTimes().size(), 37u);
}

TEST_F(ExecutorTest, AbortIsStickyUntilRearmed) {
  const std::int64_t start = head.stage().position();
  StopAfter abort_after(12, &executor);
  const ExecutionResult r = executor.run(planMove(config, 1000), &abort_after);
  EXPECT_TRUE(r.aborted);
  EXPECT_EQ(r.steps, 12);
  EXPECT_EQ(head.stage().position(), start + 12);
  EXPECT_EQ(executor.run(planMove(config, 10)).steps, 0);  // still aborted
  executor.rearm();
  head.clock().sleepUntil(head.clock().now() + 10ms);
  EXPECT_EQ(executor.run(planMove(config, 10)).steps, 10);
  EXPECT_EQ(head.stage().position(), start + 22);
}

// The head's clock with one late wake-up: the first sleep whose deadline is
// at or after `late_from` returns `lateness` after it (a preempted thread).
class LateClock final : public Clock {
 public:
  LateClock(Clock& inner, std::chrono::nanoseconds late_from, std::chrono::nanoseconds lateness)
      : inner_(inner), late_from_(late_from), lateness_(lateness) {}
  std::chrono::nanoseconds now() const override { return inner_.now(); }
  void sleepUntil(std::chrono::nanoseconds deadline) override {
    if (!done_ && deadline >= late_from_) {
      done_ = true;
      deadline += lateness_;
    }
    inner_.sleepUntil(deadline);
  }

 private:
  Clock& inner_;
  std::chrono::nanoseconds late_from_, lateness_;
  bool done_ = false;
};

// An output line that passes its levels on (to the head's line, when given)
// and records the time of each edge.
class RecordingLine final : public OutputLine {
 public:
  RecordingLine(Clock& clock, OutputLine* inner) : clock_(clock), inner_(inner) {}
  void set(bool active) override {
    if (inner_ != nullptr) inner_->set(active);
    if (active != level_) (active ? rises : falls).push_back(clock_.now());
    level_ = active;
  }
  std::vector<std::chrono::nanoseconds> rises, falls;

 private:
  Clock& clock_;
  OutputLine* inner_;
  bool level_ = false;
};

// A 4000-step move reaches the profile's 20°/s (5000 steps/s, 200 µs a step)
// after 620 steps; step 2000 is at cruise.
constexpr std::size_t kLateStep = 2000;

TEST_F(ExecutorTest, ALateWakeUpAtSpeedReRampsInsteadOfBursting) {
  const std::int64_t start = head.stage().position();
  const StepSchedule plan = planMove(config, 4000);
  const std::chrono::nanoseconds origin = head.clock().now();
  // 5 ms late at step 2000: 25 steps overdue. Emitted back to back, they are
  // a step train the head's stage model (30°/s, 120°/s² at most) stalls on.
  LateClock late(head.clock(), origin + std::chrono::nanoseconds{plan.step_ns[kLateStep]}, 5ms);
  RecordingLine steps(head.clock(), step.get());
  StepExecutor ex(late, steps, *dir);
  const ExecutionResult r = ex.run(plan, nullptr, origin);
  EXPECT_TRUE(r.complete(plan));
  EXPECT_EQ(head.stage().counters().lost, 0u);
  EXPECT_EQ(head.stage().position(), start + 4000);
  EXPECT_EQ(r.reramps, 1);
  EXPECT_EQ(ex.reramps(), 1);
  // The late step went out 5 ms late and says so.
  EXPECT_EQ(ex.stepJitter().snapshot().max, 5ms);
  const auto t = ex.stepTimes();
  ASSERT_EQ(t.size(), 4000u);
  // Never a step sooner after the one before it than planned...
  for (std::size_t k = 1; k < t.size(); ++k) {
    ASSERT_GE((t[k] - t[k - 1]).count(), plan.step_ns[k] - plan.step_ns[k - 1]) << "step " << k;
  }
  // ... and from the late step on, the motor restarts from rest: 5.2 ms
  // after the step before, it is below the start rate (2°/s). Back to 20°/s
  // at 80°/s² takes (5000 - 500) / 20000 = 0.225 s over 619 steps the plan
  // gave 0.124 s at cruise: the rest of the move runs ~0.101 s + 5 ms late.
  const double slip_s = std::chrono::duration<double>(r.slip).count();
  std::cout << "[executor] late by 5 ms at step " << kLateStep << ": slip " << slip_s * 1e3
            << " ms, " << r.reramps << " re-ramp\n";
  EXPECT_NEAR(slip_s, 0.106, 0.004);
  // Then it is on the delayed plan again: the last steps keep its intervals.
  EXPECT_EQ(t.back() - t[t.size() - 2],
            std::chrono::nanoseconds{plan.step_ns[3999] - plan.step_ns[3998]});
  EXPECT_EQ(t.back(), origin + std::chrono::nanoseconds{plan.step_ns.back()} + r.slip);
  // A late rising edge still makes a full-width pulse.
  ASSERT_EQ(steps.rises.size(), steps.falls.size());
  for (std::size_t k = 0; k < steps.rises.size(); ++k) {
    ASSERT_EQ((steps.falls[k] - steps.rises[k]).count(), plan.step_high_ns) << "step " << k;
  }
}

TEST_F(ExecutorTest, ALittleLatenessDoesNotMoveTheRestOfTheSchedule) {
  const StepSchedule plan = planMove(config, 4000);
  const std::chrono::nanoseconds origin = head.clock().now();
  // 60 µs late at step 2000, within the lag tolerance (half a full step: 5
  // microsteps, 1 ms at 200 µs a step): the step after
  // it comes on its own deadline (140 µs later), so a long scan never drifts.
  LateClock late(head.clock(), origin + std::chrono::nanoseconds{plan.step_ns[kLateStep]}, 60us);
  StepExecutor ex(late, *step, *dir);
  const ExecutionResult r = ex.run(plan, nullptr, origin);
  EXPECT_TRUE(r.complete(plan));
  EXPECT_EQ(r.reramps, 0);
  EXPECT_EQ(r.slip, 0ns);
  const auto t = ex.stepTimes();
  ASSERT_EQ(t.size(), 4000u);
  for (std::size_t k = 0; k < t.size(); ++k) {
    const std::chrono::nanoseconds planned = origin + std::chrono::nanoseconds{plan.step_ns[k]};
    ASSERT_EQ(t[k], k == kLateStep ? planned + 60us : planned) << "step " << k;
  }
}

TEST_F(ExecutorTest, TriggersStayWithTheirStepsAfterAReRamp) {
  SweepRequest req;
  req.speed_deg_s = 20;
  req.range_steps = 2000;
  for (std::int64_t o = 0; o <= 2000; o += 100)
    req.trigger_offsets.push_back(o);
  const SweepPlan sweep = planSweep(config, req);
  const StepSchedule& plan = sweep.schedule;
  const std::chrono::nanoseconds origin = head.clock().now();
  // 5 ms late in the middle of the range, between two triggers.
  const auto mid = static_cast<std::size_t>(sweep.run_up_steps + 1050);
  LateClock late(head.clock(), origin + std::chrono::nanoseconds{plan.step_ns[mid]}, 5ms);
  RecordingLine trigger(head.clock(), nullptr);
  StepExecutor ex(late, *step, *dir);
  const ExecutionResult r = ex.run(plan, trigger, nullptr, origin);
  EXPECT_TRUE(r.complete(plan));
  EXPECT_EQ(r.reramps, 1);
  EXPECT_EQ(head.stage().counters().lost, 0u);
  const auto t = ex.stepTimes();
  ASSERT_EQ(trigger.rises.size(), plan.triggers.size());
  ASSERT_EQ(trigger.falls.size(), plan.triggers.size());
  for (std::size_t i = 0; i < plan.triggers.size(); ++i) {
    // Trigger i fires right after the step it counts (lead 0), before the next.
    const auto count = static_cast<std::size_t>(plan.triggers[i].step_count);
    EXPECT_EQ(trigger.rises[i], t[count - 1]) << "trigger " << i;
    if (count < t.size()) {
      EXPECT_LT(trigger.rises[i], t[count]) << "trigger " << i;
    }
    EXPECT_EQ((trigger.falls[i] - trigger.rises[i]).count(), plan.trigger_high_ns);
  }
}

}  // namespace
}  // namespace cylscan::drivers
