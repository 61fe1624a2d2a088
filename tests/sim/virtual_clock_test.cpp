// SPDX-License-Identifier: Apache-2.0
// The virtual clock with several threads: time moves only when every
// attached thread waits, to the earliest deadline; a device event wakes a
// waiting thread before time moves on; detaching never deadlocks; threads
// that are not attached follow the attached ones.
#include <gtest/gtest.h>

#include <latch>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "drivers/sim/virtual_clock.hpp"

namespace cylscan::sim {
namespace {

using namespace std::chrono_literals;
using Log = std::vector<std::pair<std::string, std::int64_t>>;

TEST(VirtualClock, AttachedThreadsInterleaveInVirtualTimeOrder) {
  for (int run = 0; run < 20; ++run) {  // the same order whatever the OS does
    VirtualClock clock;
    std::mutex m;
    Log log;
    std::latch ready(2);
    auto worker = [&](const std::string& name, std::vector<std::chrono::milliseconds> times) {
      drivers::ClockThread participant(clock);
      ready.arrive_and_wait();
      for (const auto t : times) {
        clock.sleepUntil(t);
        std::lock_guard lock(m);
        log.emplace_back(name, clock.now().count());
      }
    };
    std::thread a(worker, "a", std::vector{10ms, 30ms, 50ms});
    std::thread b(worker, "b", std::vector{20ms, 40ms});
    a.join();
    b.join();
    const Log expected{{"a", 10'000'000},
                       {"b", 20'000'000},
                       {"a", 30'000'000},
                       {"b", 40'000'000},
                       {"a", 50'000'000}};
    ASSERT_EQ(log, expected) << "run " << run;
    EXPECT_EQ(clock.attachedThreads(), 0);
  }
}

TEST(VirtualClock, TimeWaitsForARunningThreadAndMovesOnWhenItDetaches) {
  VirtualClock clock;
  std::latch ready(2);
  std::int64_t seen_while_running = -1, woke = -1;
  std::thread sleeper([&] {
    drivers::ClockThread participant(clock);
    ready.arrive_and_wait();
    clock.sleepUntil(100ms);
    woke = clock.now().count();
  });
  std::thread busy([&] {
    drivers::ClockThread participant(clock);
    ready.arrive_and_wait();
    std::this_thread::sleep_for(30ms);  // real work, no clock wait: time must not move
    seen_while_running = clock.now().count();
  });  // detaches: the sleeper alone now, time goes to 100 ms
  busy.join();
  sleeper.join();
  EXPECT_EQ(seen_while_running, 0);
  EXPECT_EQ(woke, 100'000'000);
}

TEST(VirtualClock, AnEventWakesTheWaiterBeforeTimeMovesOn) {
  VirtualClock clock;
  std::latch ready(2);
  std::int64_t woke = -1;
  std::thread waiter([&] {
    drivers::ClockThread participant(clock);
    ready.arrive_and_wait();
    const std::uint64_t epoch = clock.eventEpoch();
    clock.waitForEvent(epoch, 1s);
    woke = clock.now().count();
  });
  std::thread producer([&] {
    drivers::ClockThread participant(clock);
    ready.arrive_and_wait();
    clock.sleepUntil(5ms);
    clock.notifyEvent();
    clock.sleepUntil(10ms);
  });
  waiter.join();
  producer.join();
  EXPECT_EQ(woke, 5'000'000);
  EXPECT_EQ(clock.now(), 10ms);
}

TEST(VirtualClock, UnattachedThreadsFollowTheAttachedOnes) {
  VirtualClock clock;
  std::latch attached(1);
  std::latch go(1);
  std::thread participant([&] {
    drivers::ClockThread p(clock);
    attached.count_down();
    go.wait();
    clock.sleepUntil(40ms);
    clock.sleepUntil(80ms);
  });
  attached.wait();
  go.count_down();
  clock.sleepUntil(60ms);  // not attached: waits until the participant moves time past it
  EXPECT_GE(clock.now(), 60ms);
  participant.join();
  EXPECT_EQ(clock.now(), 80ms);
  clock.sleepUntil(90ms);  // alone again: jumps
  EXPECT_EQ(clock.now(), 90ms);
  const std::uint64_t epoch = clock.eventEpoch();
  clock.waitForEvent(epoch, 95ms);  // alone: nothing can come, jumps to the deadline
  EXPECT_EQ(clock.now(), 95ms);
}

TEST(VirtualClock, AttachmentNestsAndIsIgnoredWhenPaced) {
  VirtualClock clock;
  {
    drivers::ClockThread outer(clock);
    drivers::ClockThread inner(clock);
    EXPECT_EQ(clock.attachedThreads(), 1);
    clock.sleepUntil(3ms);  // the only participant: time goes to its deadline
    EXPECT_EQ(clock.now(), 3ms);
  }
  EXPECT_EQ(clock.attachedThreads(), 0);
  VirtualClock paced(true);
  drivers::ClockThread p(paced);
  EXPECT_EQ(paced.attachedThreads(), 0);
  const auto t = paced.now() + 1ms;
  paced.sleepUntil(t);
  EXPECT_GE(paced.now(), t);
}

}  // namespace
}  // namespace cylscan::sim
