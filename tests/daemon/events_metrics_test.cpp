// SPDX-License-Identifier: Apache-2.0
// The event hub's bounded queues and the Prometheus text of the metrics.
#include <thread>

#include <gtest/gtest.h>

#include "firmware/daemon/event_hub.hpp"
#include "firmware/daemon/metrics.hpp"

namespace cylscan::firmware {
namespace {

using namespace std::chrono_literals;

TEST(EventHub, ASubscriberGetsTheEventsAfterItSubscribedInOrder) {
  EventHub hub(16);
  hub.publish("state", {{"state", "idle"}});
  auto stream = hub.subscribe(HeadEvent{0, "state", {{"state", "idle"}}});
  hub.publish("progress", {{"frames_done", 1}});
  hub.publish("progress", {{"frames_done", 2}});
  auto first = stream->next(0ms);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->name, "state");
  auto a = stream->next(0ms);
  auto b = stream->next(0ms);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->data["frames_done"], 1);
  EXPECT_EQ(b->data["frames_done"], 2);
  EXPECT_LT(first->seq, a->seq);
  EXPECT_LT(a->seq, b->seq);
  EXPECT_FALSE(stream->next(0ms));
  EXPECT_FALSE(stream->closed());
  EXPECT_EQ(stream->dropped(), 0u);
}

TEST(EventHub, AFullQueueDropsItsOldestAndCountsThem) {
  EventHub hub(3);
  auto stream = hub.subscribe();
  for (int i = 1; i <= 5; ++i)
    hub.publish("progress", {{"frames_done", i}});
  EXPECT_EQ(stream->dropped(), 2u);
  for (int i = 3; i <= 5; ++i) {
    auto e = stream->next(0ms);
    ASSERT_TRUE(e);
    EXPECT_EQ(e->data["frames_done"], i);
  }
}

TEST(EventHub, NextWakesForAnEventAndCloseEndsTheStreams) {
  EventHub hub;
  auto stream = hub.subscribe();
  EXPECT_EQ(hub.subscribers(), 1u);
  std::thread publisher([&] { hub.publish("scan", {{"id", "x"}}); });
  auto e = stream->next(10s);  // returns when the event comes
  publisher.join();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->name, "scan");
  std::thread closer([&] { hub.close(); });
  EXPECT_FALSE(stream->next(10s));  // returns when closed
  closer.join();
  EXPECT_TRUE(stream->closed());
  EXPECT_TRUE(hub.subscribe()->closed());  // after close, streams start closed
  stream.reset();
  EXPECT_EQ(hub.subscribers(), 0u);
}

TEST(Metrics, HistogramBucketsAreCumulative) {
  Histogram h({1.0, 2.0, 5.0});
  for (double v : {0.5, 1.0, 1.5, 3.0, 7.0})
    h.observe(v);
  const auto s = h.snapshot();
  EXPECT_EQ(s.counts, (std::vector<std::uint64_t>{2, 3, 4}));
  EXPECT_EQ(s.count, 5u);
  EXPECT_DOUBLE_EQ(s.sum, 13.0);
  EXPECT_THROW(Histogram({2.0, 1.0}), std::invalid_argument);
}

TEST(Metrics, JitterBucketsFoldIntoPrometheusBuckets) {
  drivers::JitterStats stats;
  for (int us : {0, 0, 1, 3, 7, 40, 1500})
    stats.record(std::chrono::microseconds(us));
  const auto h = foldJitter(stats.snapshot(), {1e-6, 5e-6, 50e-6});
  EXPECT_EQ(h.count, 7u);
  // Edges at 0 µs fall in [0, 1) µs: at or below 1 µs; 1 µs in [1, 2).
  EXPECT_EQ(h.counts, (std::vector<std::uint64_t>{2, 4, 6}));
  EXPECT_NEAR(h.sum, (0.5 + 0.5 + 1.5 + 3.5 + 7.5 + 40.5 + 1500.5) * 1e-6, 1e-9);
}

TEST(Metrics, TextExposition) {
  MetricsWriter w;
  LabelledCounter scans;
  scans.inc("done", 3);
  scans.inc("failed");
  w.counter("cylscan_scans_total", "Scans.", "result", scans.values());
  Histogram h({0.5});
  h.observe(0.25);
  w.histogram("cylscan_scan_duration_seconds", "Durations.", h.snapshot());
  w.gauge("cylscan_sse_clients", "Clients.", 2);
  const std::string& t = w.text();
  EXPECT_NE(t.find("# TYPE cylscan_scans_total counter\n"), std::string::npos) << t;
  EXPECT_NE(t.find("cylscan_scans_total{result=\"done\"} 3\n"), std::string::npos) << t;
  EXPECT_NE(t.find("cylscan_scans_total{result=\"failed\"} 1\n"), std::string::npos) << t;
  EXPECT_NE(t.find("cylscan_scan_duration_seconds_bucket{le=\"0.5\"} 1\n"), std::string::npos) << t;
  EXPECT_NE(t.find("cylscan_scan_duration_seconds_bucket{le=\"+Inf\"} 1\n"), std::string::npos)
      << t;
  EXPECT_NE(t.find("cylscan_scan_duration_seconds_sum 0.25\n"), std::string::npos) << t;
  EXPECT_NE(t.find("cylscan_scan_duration_seconds_count 1\n"), std::string::npos) << t;
  EXPECT_NE(t.find("cylscan_sse_clients 2\n"), std::string::npos) << t;
  EXPECT_EQ(escapeLabelValue("a\"b\\c\nd"), "a\\\"b\\\\c\\nd");
}

}  // namespace
}  // namespace cylscan::firmware
