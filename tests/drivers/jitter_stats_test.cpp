// SPDX-License-Identifier: Apache-2.0
// The lateness histogram: counts, percentiles from the buckets, max, the
// overflow bucket, and snapshots taken while another thread records.
#include <gtest/gtest.h>

#include <thread>

#include "drivers/jitter_stats.hpp"

namespace cylscan::drivers {
namespace {

using namespace std::chrono_literals;

TEST(JitterStats, PercentilesAndMax) {
  JitterStats j;
  EXPECT_EQ(j.snapshot().count, 0u);
  EXPECT_EQ(j.snapshot().p99, 0ns);
  // 90 edges at 3.5 µs, 9 at 40.2 µs, 1 at 700 µs.
  for (int i = 0; i < 90; ++i)
    j.record(3500ns);
  for (int i = 0; i < 9; ++i)
    j.record(40200ns);
  j.record(700us);
  const JitterStats::Snapshot s = j.snapshot();
  EXPECT_EQ(s.count, 100u);
  EXPECT_EQ(s.p50, 4us);  // upper edge of the 3–4 µs bucket
  EXPECT_EQ(s.p99, 41us);
  EXPECT_EQ(s.max, 700us);
  EXPECT_EQ(s.min, 3500ns);
  EXPECT_EQ(s.buckets[3], 90u);
  EXPECT_EQ(s.buckets[40], 9u);
  EXPECT_EQ(s.buckets[700], 1u);
  j.reset();
  EXPECT_EQ(j.snapshot().count, 0u);
}

TEST(JitterStats, LateEdgesBeyondTheHistogramKeepTheirMax) {
  JitterStats j;
  j.record(5ms);
  j.record(-2us);  // early (cannot happen with an absolute sleep): bucket 0
  const auto s = j.snapshot();
  EXPECT_EQ(s.buckets.back(), 1u);
  EXPECT_EQ(s.buckets.front(), 1u);
  EXPECT_EQ(s.p99, 5ms);
  EXPECT_EQ(s.max, 5ms);
  EXPECT_EQ(s.min, -2us);
}

TEST(JitterStats, SnapshotsWhileRecording) {
  JitterStats j;
  constexpr int kEdges = 200000;
  std::thread writer([&] {
    for (int i = 0; i < kEdges; ++i)
      j.record(std::chrono::nanoseconds{(i % 50) * 1000});
  });
  std::uint64_t last = 0;
  while (last < kEdges) {
    const auto s = j.snapshot();
    ASSERT_GE(s.count, last);  // never goes back
    ASSERT_LE(s.p50, s.p99);
    last = s.count;
    if (s.count == kEdges) break;
  }
  writer.join();
  const auto s = j.snapshot();
  EXPECT_EQ(s.count, static_cast<std::uint64_t>(kEdges));
  EXPECT_EQ(s.max, 49us);
  EXPECT_EQ(s.p50, 25us);
}

}  // namespace
}  // namespace cylscan::drivers
