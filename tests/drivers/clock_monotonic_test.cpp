// SPDX-License-Identifier: Apache-2.0
// The real clock: monotone, absolute sleeps that never return early, and
// signals (EINTR) do not cut a sleep short. No timing bounds are asserted.
#include <gtest/gtest.h>

#include <pthread.h>
#include <signal.h>

#include <atomic>
#include <thread>

#include "drivers/clock_monotonic.hpp"

namespace cylscan::drivers {
namespace {

using namespace std::chrono_literals;

TEST(MonotonicClock, NeverGoesBackAndSleepsToAnAbsoluteDeadline) {
  MonotonicClock clock;
  auto previous = clock.now();
  for (int i = 0; i < 1000; ++i) {
    const auto t = clock.now();
    ASSERT_GE(t, previous);
    previous = t;
  }
  const auto deadline = clock.now() + 2ms;
  clock.sleepUntil(deadline);
  EXPECT_GE(clock.now(), deadline);
  const auto before = clock.now();
  clock.sleepUntil(before - 1s);  // in the past: returns at once
  clock.sleepUntil(std::chrono::nanoseconds{0});
}

std::atomic<int> g_signals{0};
void onSignal(int) {
  g_signals.fetch_add(1);
}

TEST(MonotonicClock, SignalsDoNotEndASleepEarly) {
  struct sigaction action {};
  action.sa_handler = onSignal;  // no SA_RESTART: clock_nanosleep returns EINTR
  sigemptyset(&action.sa_mask);
  struct sigaction old {};
  ASSERT_EQ(sigaction(SIGUSR1, &action, &old), 0);
  MonotonicClock clock;
  const auto deadline = clock.now() + 150ms;
  std::atomic<bool> done{false};
  std::chrono::nanoseconds woke{0};
  std::thread sleeper([&] {
    clock.sleepUntil(deadline);
    woke = clock.now();
    done = true;
  });
  const pthread_t handle = sleeper.native_handle();
  int sent = 0;
  while (!done && sent < 20) {
    pthread_kill(handle, SIGUSR1);
    ++sent;
    std::this_thread::sleep_for(2ms);
  }
  sleeper.join();
  sigaction(SIGUSR1, &old, nullptr);
  EXPECT_GT(g_signals.load(), 0);
  EXPECT_GE(woke, deadline);
}

}  // namespace
}  // namespace cylscan::drivers
