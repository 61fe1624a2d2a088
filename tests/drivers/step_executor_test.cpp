// The executor against the virtual head: the stage executes exactly the
// planned steps, edges land on their deadlines in virtual time, the lines
// are left low, abort and stop conditions end a run at a step boundary.
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace cylscan::drivers
