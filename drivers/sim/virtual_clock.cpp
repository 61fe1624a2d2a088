// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/virtual_clock.hpp"

#include <algorithm>
#include <limits>

namespace cylscan::sim {

VirtualClock::VirtualClock(bool paced) : paced_(paced), origin_(std::chrono::steady_clock::now()) {}

VirtualClock::Nanoseconds VirtualClock::now() const {
  if (paced_) {
    return std::chrono::duration_cast<Nanoseconds>(std::chrono::steady_clock::now() - origin_);
  }
  return Nanoseconds{now_ns_.load(std::memory_order_acquire)};
}

int VirtualClock::attachedThreads() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(attached_.size());
}

bool VirtualClock::attachedLocked(std::thread::id id) const {
  return std::any_of(attached_.begin(), attached_.end(),
                     [id](const auto& a) { return a.first == id; });
}

void VirtualClock::attachThread() {
  if (paced_) return;
  std::lock_guard lock(mutex_);
  const std::thread::id id = std::this_thread::get_id();
  for (auto& a : attached_) {
    if (a.first == id) {
      ++a.second;
      return;
    }
  }
  attached_.emplace_back(id, 1);
}

void VirtualClock::detachThread() {
  if (paced_) return;
  std::lock_guard lock(mutex_);
  const std::thread::id id = std::this_thread::get_id();
  const auto it = std::find_if(attached_.begin(), attached_.end(),
                               [id](const auto& a) { return a.first == id; });
  if (it == attached_.end()) return;
  if (--it->second > 0) return;
  attached_.erase(it);
  // The others may all be waiting for this one: let time move on (or, with
  // nothing attached, let the waiting observers jump it themselves).
  scheduleLocked();
  cv_.notify_all();
}

void VirtualClock::jumpLocked(Nanoseconds deadline) {
  if (deadline.count() > now_ns_.load(std::memory_order_relaxed)) {
    now_ns_.store(deadline.count(), std::memory_order_release);
  }
}

// Releases the waits that are over: deadline reached, or an event since.
bool VirtualClock::releaseSatisfiedLocked(const Waiter* self, bool& others) {
  const std::int64_t now = now_ns_.load(std::memory_order_relaxed);
  const std::uint64_t epoch = epoch_.load(std::memory_order_seq_cst);
  bool any = false;
  for (Waiter* w = waiters_; w != nullptr; w = w->next) {
    if (w->released) continue;
    if (w->deadline.count() <= now || (w->event && w->seen != epoch)) {
      w->released = true;
      --waiting_;
      any = true;
      others = others || w != self;
    }
  }
  return any;
}

void VirtualClock::scheduleLocked(const Waiter* self) {
  const std::uint64_t epoch = epoch_.load(std::memory_order_seq_cst);
  // Threads outside the clock wait for an event or for time to move.
  bool wake = epoch != notified_epoch_ || unattached_waiting_ > 0;
  notified_epoch_ = epoch;
  if (!attached_.empty() && waiting_ >= static_cast<int>(attached_.size())) {
    bool others = false;
    if (!releaseSatisfiedLocked(self, others)) {
      std::int64_t earliest = std::numeric_limits<std::int64_t>::max();
      for (const Waiter* w = waiters_; w != nullptr; w = w->next) {
        if (!w->released) earliest = std::min(earliest, w->deadline.count());
      }
      if (earliest != std::numeric_limits<std::int64_t>::max()) {
        jumpLocked(Nanoseconds{earliest});
        releaseSatisfiedLocked(self, others);
      }
    }
    wake = wake || others;
  }
  if (wake) cv_.notify_all();
}

void VirtualClock::waitUnattached(std::unique_lock<std::mutex>& lock) {
  ++unattached_waiting_;
  cv_.wait(lock);
  --unattached_waiting_;
}

void VirtualClock::waitAttached(Waiter& w, std::unique_lock<std::mutex>& lock) {
  w.next = waiters_;
  waiters_ = &w;
  ++waiting_;
  scheduleLocked(&w);
  cv_.wait(lock, [&w] { return w.released; });
  Waiter** link = &waiters_;
  while (*link != &w)
    link = &(*link)->next;
  *link = w.next;
}

void VirtualClock::sleepUntil(Nanoseconds deadline) {
  if (paced_) {
    std::this_thread::sleep_until(origin_ + deadline);
    return;
  }
  std::unique_lock lock(mutex_);
  if (deadline.count() <= now_ns_.load(std::memory_order_relaxed)) return;
  if (attachedLocked(std::this_thread::get_id())) {
    Waiter w;
    w.deadline = deadline;
    waitAttached(w, lock);
    return;
  }
  // Not attached: wait for the attached threads to move time; alone, jump.
  for (;;) {
    if (attached_.empty()) {
      jumpLocked(deadline);
      scheduleLocked();
      return;
    }
    if (deadline.count() <= now_ns_.load(std::memory_order_relaxed)) return;
    waitUnattached(lock);
  }
}

void VirtualClock::waitForEvent(std::uint64_t seen_epoch, Nanoseconds deadline) {
  if (paced_) {
    const Nanoseconds now_paced = now();
    if (now_paced >= deadline || eventEpoch() != seen_epoch) return;
    std::this_thread::sleep_until(origin_ +
                                  std::min(deadline, now_paced + std::chrono::microseconds(200)));
    return;
  }
  std::unique_lock lock(mutex_);
  auto over = [&] {
    return deadline.count() <= now_ns_.load(std::memory_order_relaxed) ||
           epoch_.load(std::memory_order_seq_cst) != seen_epoch;
  };
  if (over()) return;
  if (attachedLocked(std::this_thread::get_id())) {
    Waiter w;
    w.deadline = deadline;
    w.event = true;
    w.seen = seen_epoch;
    waitAttached(w, lock);
    return;
  }
  for (;;) {
    if (attached_.empty()) {  // nothing can happen unless this thread acts
      jumpLocked(deadline);
      scheduleLocked();
      return;
    }
    if (over()) return;
    waitUnattached(lock);
  }
}

}  // namespace cylscan::sim
