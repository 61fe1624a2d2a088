// SPDX-License-Identifier: Apache-2.0
// Fixed-capacity rings for the real-time paths of the virtual head: writing
// never allocates or locks. One writer (the thread that drives the output
// lines), one reader.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>

namespace cylscan::sim {

// A queue: push fails (returns false) when full.
template <typename T, std::size_t N>
class SpscQueue {
 public:
  bool push(const T& value) {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= N) return false;
    items_[head % N] = value;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  std::optional<T> front() const {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return std::nullopt;
    return items_[tail % N];
  }
  void pop() { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  bool empty() const {
    return tail_.load(std::memory_order_relaxed) == head_.load(std::memory_order_acquire);
  }
  void clear() { tail_.store(head_.load(std::memory_order_acquire), std::memory_order_release); }

 private:
  std::array<T, N> items_{};
  std::atomic<std::uint64_t> head_{0};
  std::atomic<std::uint64_t> tail_{0};
};

// A history: push always succeeds and overwrites the oldest entry.
template <typename T, std::size_t N>
class HistoryRing {
 public:
  void push(const T& value) {
    const std::uint64_t n = count_.load(std::memory_order_relaxed);
    items_[n % N] = value;
    count_.store(n + 1, std::memory_order_release);
  }
  std::uint64_t count() const { return count_.load(std::memory_order_acquire); }
  std::uint64_t oldest() const { return count() > N ? count() - N : 0; }
  const T& at(std::uint64_t index) const {
    return items_[index % N];
  }  // oldest() <= index < count()

 private:
  std::array<T, N> items_{};
  std::atomic<std::uint64_t> count_{0};
};

}  // namespace cylscan::sim
