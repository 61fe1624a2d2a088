// SPDX-License-Identifier: Apache-2.0
// Lateness of real-time edges (actual time after the edge minus its
// deadline) as a fixed-bucket histogram with p50/p99/max. One thread records
// (no allocation, no lock); any thread may take a snapshot, e.g. a daemon
// reporting the executor's figures.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <vector>

namespace cylscan::drivers {

class JitterStats {
 public:
  static constexpr int kBuckets = 2000;  // 1 µs each; the last one also takes everything later
  static constexpr std::chrono::nanoseconds kBucketWidth{1000};

  struct Snapshot {
    std::uint64_t count = 0;
    std::chrono::nanoseconds p50{0};  // upper edge of the bucket holding the percentile,
    std::chrono::nanoseconds p99{0};  // capped at max (0 when empty)
    std::chrono::nanoseconds max{0};
    std::chrono::nanoseconds min{0};
    std::chrono::nanoseconds bucket_width = kBucketWidth;
    std::vector<std::uint64_t> buckets;  // kBuckets counts (early edges count as 0)
  };

  void record(std::chrono::nanoseconds lateness) noexcept;
  // Each figure is consistent; taken during recording, the set may lag by
  // the edges in flight.
  Snapshot snapshot() const;
  void reset() noexcept;  // by the recording thread, or when it is idle

 private:
  std::array<std::atomic<std::uint64_t>, kBuckets> buckets_{};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::int64_t> max_ns_{0};
  std::atomic<std::int64_t> min_ns_{0};
};

}  // namespace cylscan::drivers
