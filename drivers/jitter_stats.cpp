// SPDX-License-Identifier: Apache-2.0
#include "drivers/jitter_stats.hpp"

#include <algorithm>

namespace cylscan::drivers {

void JitterStats::record(std::chrono::nanoseconds lateness) noexcept {
  const std::int64_t ns = lateness.count();
  const std::int64_t index = std::clamp<std::int64_t>(ns / kBucketWidth.count(), 0, kBuckets - 1);
  // A single writer: plain load/store pairs are enough and stay wait-free.
  auto& bucket = buckets_[static_cast<std::size_t>(index)];
  bucket.store(bucket.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  const std::uint64_t n = count_.load(std::memory_order_relaxed);
  if (n == 0 || ns > max_ns_.load(std::memory_order_relaxed)) {
    max_ns_.store(ns, std::memory_order_relaxed);
  }
  if (n == 0 || ns < min_ns_.load(std::memory_order_relaxed)) {
    min_ns_.store(ns, std::memory_order_relaxed);
  }
  count_.store(n + 1, std::memory_order_release);
}

void JitterStats::reset() noexcept {
  count_.store(0, std::memory_order_relaxed);
  for (auto& b : buckets_)
    b.store(0, std::memory_order_relaxed);
  max_ns_.store(0, std::memory_order_relaxed);
  min_ns_.store(0, std::memory_order_release);
}

JitterStats::Snapshot JitterStats::snapshot() const {
  Snapshot s;
  s.buckets.resize(kBuckets);
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < kBuckets; ++i) {
    s.buckets[i] = buckets_[i].load(std::memory_order_relaxed);
    total += s.buckets[i];
  }
  s.count = total;
  if (total == 0) return s;
  s.max = std::chrono::nanoseconds{max_ns_.load(std::memory_order_relaxed)};
  s.min = std::chrono::nanoseconds{min_ns_.load(std::memory_order_relaxed)};
  // The bucket holding the rank ceil(q·n), reported by its upper edge.
  auto percentile = [&](std::uint64_t per_mille) {
    const std::uint64_t rank = std::max<std::uint64_t>(1, (total * per_mille + 999) / 1000);
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBuckets; ++i) {
      seen += s.buckets[i];
      if (seen >= rank) {
        if (i + 1 == kBuckets) return s.max;  // the overflow bucket
        const auto upper = kBucketWidth * static_cast<std::int64_t>(i + 1);
        return std::min(upper, std::max(s.max, std::chrono::nanoseconds{0}));
      }
    }
    return s.max;
  };
  s.p50 = percentile(500);
  s.p99 = percentile(990);
  return s;
}

}  // namespace cylscan::drivers
