// SPDX-License-Identifier: Apache-2.0
// The real-time worker: SCHED_FIFO and locked memory when the machine allows,
// a warning and normal priority when it does not (forced here by dropping
// the privilege in a child process), exceptions carried to join(), and a
// short real-time run of the executor on the real clock whose jitter figures
// are printed (never asserted: they depend on the machine).
#include <gtest/gtest.h>

#include <grp.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdlib>
#include <iostream>
#include <stdexcept>

#include "drivers/clock_monotonic.hpp"
#include "drivers/realtime_thread.hpp"
#include "drivers/step_executor.hpp"
#include "drivers_test_support.hpp"

namespace cylscan::drivers {
namespace {

int policyOfThisThread() {
  int policy = -1;
  sched_param param{};
  pthread_getschedparam(pthread_self(), &policy, &param);
  return policy;
}

TEST(RealtimeThread, ReportsWhatItGot) {
  int policy = -1;
  RealtimeOptions options;
  options.priority = 10;
  options.lock_memory = false;  // the process stays unlocked for the other tests
  RealtimeThread t([&] { policy = policyOfThisThread(); }, options);
  t.join();
  EXPECT_EQ(policy == SCHED_FIFO, t.realtime());
  EXPECT_EQ(t.warnings().empty(), t.realtime());
  EXPECT_FALSE(t.memoryLocked());
  std::cout << "[ info ] SCHED_FIFO " << (t.realtime() ? "granted" : "not granted") << "\n";
}

TEST(RealtimeThread, CarriesTheBodysExceptionAndChecksThePriority) {
  RealtimeOptions options;
  options.lock_memory = false;
  RealtimeThread t([] { throw std::runtime_error("boom"); }, options);
  EXPECT_THROW(t.join(), std::runtime_error);
  options.priority = 1000;
  EXPECT_THROW(RealtimeThread([] {}, options), std::invalid_argument);
}

// In a fresh child: drop every privilege (an unprivileged user, no real-time
// priority, no locked memory allowed), then ask for SCHED_FIFO and mlockall.
// Exit 0 only if the thread ran at normal priority with both warnings.
void degradedChild() {
  const rlimit zero{0, 0};
  if (setrlimit(RLIMIT_RTPRIO, &zero) != 0 || setrlimit(RLIMIT_MEMLOCK, &zero) != 0) std::_Exit(2);
  if (geteuid() == 0) {
    const gid_t nogroup = 65534;
    if (setgroups(0, nullptr) != 0 || setgid(nogroup) != 0 || setuid(65534) != 0) std::_Exit(3);
  }
  int policy = -1;
  RealtimeThread t([&] { policy = policyOfThisThread(); }, RealtimeOptions{});
  t.join();
  const bool warned_fifo =
      !t.warnings().empty() && t.warnings()[0].find("SCHED_FIFO") != std::string::npos;
  const bool warned_lock =
      t.warnings().size() == 2 && t.warnings()[1].find("mlockall") != std::string::npos;
  std::_Exit(!t.realtime() && !t.memoryLocked() && policy == SCHED_OTHER && warned_fifo &&
                     warned_lock
                 ? 0
                 : 4);
}

TEST(RealtimeThreadDeathTest, WithoutPrivilegeItRunsAtNormalPriorityWithWarnings) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(degradedChild(), ::testing::ExitedWithCode(0), "");
}

void print(const char* what, const JitterStats::Snapshot& s) {
  std::cout << "[ info ] " << what << " lateness: n=" << s.count
            << " p50=" << s.p50.count() / 1000.0 << " us p99=" << s.p99.count() / 1000.0
            << " us max=" << s.max.count() / 1000.0 << " us\n";
}

TEST(RealtimeThread, ShortRealClockRunOfTheExecutor) {
  MonotonicClock clock;
  test::CountingLine step, dir, trigger;
  StepExecutor executor(clock, step, dir, &trigger);
  const StageConfig c;
  SweepRequest r;
  r.speed_deg_s = 10;
  r.range_steps = 1000;  // 0.4 s at 2500 steps/s
  for (int k = 0; k < 20; ++k)
    r.trigger_offsets.push_back(50 * k);
  const SweepPlan plan = planSweep(c, r);
  executor.reserve(plan.schedule.steps());
  ExecutionResult result;
  RealtimeOptions options;
  options.priority = 50;
  RealtimeThread t([&] { result = executor.run(plan.schedule); }, options);
  t.join();
  if (t.memoryLocked()) munlockall();  // leave the test process as it was
  for (const std::string& w : t.warnings())
    std::cout << "[ info ] " << w << "\n";
  EXPECT_TRUE(result.complete(plan.schedule));
  EXPECT_EQ(step.rising.load(), plan.schedule.steps());
  EXPECT_EQ(trigger.rising.load(), 20);
  const auto steps = executor.stepJitter().snapshot();
  const auto triggers = executor.triggerJitter().snapshot();
  EXPECT_EQ(steps.count, static_cast<std::uint64_t>(plan.schedule.steps()));
  EXPECT_EQ(triggers.count, 20u);
  // An absolute sleep never returns before its deadline: no edge is early.
  EXPECT_GE(steps.min.count(), 0);
  EXPECT_LE(steps.p50, steps.p99);
  EXPECT_LE(steps.p99, steps.max);
  std::cout << "[ info ] real clock, " << (t.realtime() ? "SCHED_FIFO" : "normal priority")
            << (t.memoryLocked() ? ", memory locked" : "") << "\n";
  print("step", steps);
  print("trigger", triggers);
}

}  // namespace
}  // namespace cylscan::drivers
