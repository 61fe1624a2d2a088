// SPDX-License-Identifier: Apache-2.0
// The virtual head's clock: a discrete-event clock in virtual time, or
// (paced) the real monotonic time since the head was made.
//
// Virtual time moves only by waits, and only to deadlines someone waits for:
//  - no thread attached (drivers::ClockThread): a wait jumps time to its
//    deadline at once (single-threaded firmware runs as fast as the CPU);
//  - threads attached: time advances only when every attached thread waits,
//    to the earliest deadline among them. A thread waiting for a device event
//    (a frame, an input edge) is woken, before time moves on, when a device
//    reports one (notifyEvent), and re-checks. Threads that are not attached
//    wait for the attached ones to move time, and jump it themselves once
//    none is attached any more.
// The virtual times this produces depend only on what the threads do, never
// on how the OS schedules them.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "drivers/clock.hpp"

namespace cylscan::sim {

class VirtualClock : public drivers::Clock {
 public:
  using Nanoseconds = std::chrono::nanoseconds;

  explicit VirtualClock(bool paced = false);
  Nanoseconds now() const override;
  void sleepUntil(Nanoseconds deadline) override;
  void attachThread() override;
  void detachThread() override;
  bool paced() const { return paced_; }

  // The devices' wake-up hook: something a waiting thread may be waiting for
  // happened (a frame became pending, an input edge was queued). Lock- and
  // allocation-free: the output lines' real-time path calls it.
  void notifyEvent() { epoch_.fetch_add(1, std::memory_order_seq_cst); }
  // Read it before checking for the event, then waitForEvent(epoch, ...).
  std::uint64_t eventEpoch() const { return epoch_.load(std::memory_order_seq_cst); }
  // Returns when an event was notified after `seen_epoch` was read, or at
  // `deadline` (virtual), whichever comes first; the caller re-checks. With
  // nothing attached it jumps to the deadline; paced, it returns after at most
  // 200 µs of real time.
  void waitForEvent(std::uint64_t seen_epoch, Nanoseconds deadline);

  int attachedThreads() const;

 private:
  struct Waiter {
    Nanoseconds deadline{0};
    bool event = false;  // also released by an event after `seen`
    std::uint64_t seen = 0;
    bool released = false;
    Waiter* next = nullptr;
  };
  bool attachedLocked(std::thread::id id) const;
  void waitAttached(Waiter& w, std::unique_lock<std::mutex>& lock);
  // Releases every waiter whose deadline has come or whose event happened;
  // true if it released any. `others` is set when one of them is not `self`.
  bool releaseSatisfiedLocked(const Waiter* self, bool& others);
  // Moves time when every attached thread waits, and wakes the threads that
  // must look again. A thread that only releases itself (`self`: the usual
  // step of a motion loop) wakes nobody: one thread's run of short waits
  // costs no context switch.
  void scheduleLocked(const Waiter* self = nullptr);
  // Runs an unattached thread's wait on the condition variable, counted so
  // that moving time wakes it.
  void waitUnattached(std::unique_lock<std::mutex>& lock);
  void jumpLocked(Nanoseconds deadline);

  bool paced_;
  std::chrono::steady_clock::time_point origin_;
  std::atomic<std::int64_t> now_ns_{0};
  std::atomic<std::uint64_t> epoch_{0};

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<std::pair<std::thread::id, int>> attached_;  // thread, nesting depth
  int waiting_ = 0;             // attached threads waiting and not yet released
  int unattached_waiting_ = 0;  // threads not attached, blocked until time or an event moves
  Waiter* waiters_ = nullptr;   // the attached threads' waits (on their stacks)
  std::uint64_t notified_epoch_ = 0;
};

}  // namespace cylscan::sim
