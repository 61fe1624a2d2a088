// SPDX-License-Identifier: Apache-2.0
// A recorder of output-line edges for golden traces: every change of an
// output line's level, with its virtual time. Recording neither allocates
// nor locks (a buffer reserved by start()); start() and take() are called
// while no thread drives the lines.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cylscan::sim {

template <typename Role>
class EdgeTrace {
 public:
  struct Edge {
    Role role{};
    bool active = false;
    std::chrono::nanoseconds time{0};
  };

  void start(std::size_t capacity) {
    recording_.store(false, std::memory_order_release);
    edges_.assign(capacity, Edge{});
    count_.store(0, std::memory_order_relaxed);
    recording_.store(true, std::memory_order_release);
  }
  void record(Role role, bool active, std::chrono::nanoseconds time) {
    if (!recording_.load(std::memory_order_acquire)) return;
    const std::size_t i = count_.fetch_add(1, std::memory_order_relaxed);
    if (i < edges_.size()) edges_[i] = Edge{role, active, time};
  }
  bool recording() const { return recording_.load(std::memory_order_acquire); }
  // Stops recording; the edges in order, and how many did not fit.
  std::vector<Edge> take(std::size_t* overflow) {
    recording_.store(false, std::memory_order_release);
    const std::size_t n = count_.load(std::memory_order_relaxed);
    std::vector<Edge> out(edges_.begin(),
                          edges_.begin() + static_cast<std::ptrdiff_t>(std::min(n, edges_.size())));
    if (overflow) *overflow = n > edges_.size() ? n - edges_.size() : 0;
    edges_.clear();
    count_.store(0, std::memory_order_relaxed);
    return out;
  }

 private:
  std::vector<Edge> edges_;
  std::atomic<std::size_t> count_{0};
  std::atomic<bool> recording_{false};
};

}  // namespace cylscan::sim
