// SPDX-License-Identifier: Apache-2.0
// GET /api/v1/events (server-sent events) and GET /metrics of a running
// cylscand during and after one scan.
#include <condition_variable>
#include <mutex>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

struct Event {
  std::string name;
  json data;
  long long id = -1;
};

// The complete events ("…\n\n"-terminated blocks) in `text`; comments skipped.
std::vector<Event> parseEvents(const std::string& text) {
  std::vector<Event> events;
  std::size_t start = 0;
  for (std::size_t end; (end = text.find("\n\n", start)) != std::string::npos; start = end + 2) {
    std::istringstream block(text.substr(start, end - start));
    Event e;
    std::string data;
    bool any = false;
    for (std::string line; std::getline(block, line);) {
      if (line.rfind("event: ", 0) == 0) {
        e.name = line.substr(7);
        any = true;
      } else if (line.rfind("data: ", 0) == 0) {
        data += line.substr(6);
        any = true;
      } else if (line.rfind("id: ", 0) == 0) {
        e.id = std::stoll(line.substr(4));
      }
    }
    if (!any) continue;
    e.data = json::parse(data, nullptr, false);
    events.push_back(std::move(e));
  }
  return events;
}

// The stream on its own thread; the events so far on request.
class EventListener {
 public:
  explicit EventListener(const HttpClient& client)
      : thread_([this, &client] {
          response_ = client.stream(
              "/api/v1/events",
              [this](const std::string& chunk) {
                std::lock_guard lock(mutex_);
                text_ += chunk;
                cv_.notify_all();
                return !stop_;
              },
              std::chrono::seconds(120));
          std::lock_guard lock(mutex_);
          ended_ = true;
          cv_.notify_all();
        }) {}
  ~EventListener() { stop(); }

  // Waits until `done(events)` holds or `timeout` passes; the events.
  std::vector<Event> waitFor(const std::function<bool(const std::vector<Event>&)>& done,
                             std::chrono::seconds timeout) {
    std::unique_lock lock(mutex_);
    std::vector<Event> events;
    cv_.wait_for(lock, timeout, [&] {
      events = parseEvents(text_);
      return ended_ || done(events);
    });
    return parseEvents(text_);
  }
  HttpResponse stop() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    if (thread_.joinable()) thread_.join();
    return response_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::string text_;
  bool stop_ = false, ended_ = false;
  HttpResponse response_;
  std::thread thread_;
};

bool hasDoneScan(const std::vector<Event>& events, const std::string& id) {
  for (const auto& e : events)
    if (e.name == "scan" && e.data.value("id", "") == id &&
        (e.data.value("state", "") == "done" || e.data.value("state", "") == "failed"))
      return true;
  return false;
}

TEST(DaemonEvents, OneScanStreamsStateProgressAndTheScan) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  EventListener listener(client);
  const auto first = listener.waitFor([](const std::vector<Event>& e) { return !e.empty(); },
                                      std::chrono::seconds(10));
  ASSERT_FALSE(first.empty()) << "no event on connect" << daemon.stderrTail();
  EXPECT_EQ(first[0].name, "state");
  EXPECT_EQ(first[0].data.value("state", ""), "idle") << first[0].data.dump();

  const std::string id = startScan(client, {{"frames", 5}, {"save_bundle", false}});
  ASSERT_FALSE(id.empty());
  const auto events = listener.waitFor(
      [&](const std::vector<Event>& e) { return hasDoneScan(e, id); }, std::chrono::seconds(60));
  const HttpResponse stream = listener.stop();
  EXPECT_EQ(stream.status, 200) << stream.describe();
  EXPECT_EQ(stream.header("content-type").rfind("text/event-stream", 0), 0u)
      << stream.header("content-type");
  ASSERT_TRUE(hasDoneScan(events, id)) << stream.body.substr(0, 3000);

  long long last_id = -1;
  int last_frame = 0, frames_total = 0;
  std::string first_set;
  bool second_seen = false, scanning_seen = false, idle_after = false, progress_seen = false;
  double last_progress = 0;
  std::string done_state;
  for (const auto& e : events) {
    EXPECT_FALSE(e.data.is_discarded()) << e.name << ": data is not JSON";
    EXPECT_GT(e.id, last_id) << "event ids increase";
    last_id = e.id;
    if (e.name == "state") {
      if (e.data.value("state", "") == "scanning") {
        scanning_seen = true;
        EXPECT_EQ(e.data.value("scan", json()), id) << e.data.dump();
      } else if (scanning_seen && e.data.value("state", "") == "idle") {
        idle_after = true;
      }
    } else if (e.name == "progress") {
      EXPECT_TRUE(scanning_seen) << "progress before the state says scanning";
      progress_seen = true;
      EXPECT_EQ(e.data.value("id", ""), id);
      const int done = e.data.value("frames_done", -1);
      frames_total = e.data.value("frames_total", -1);
      EXPECT_EQ(done, last_frame + 1) << "one progress event per frame: " << e.data.dump();
      last_frame = done;
      const double p = e.data.value("progress", -1.0);
      EXPECT_GE(p, last_progress);
      EXPECT_LE(p, 1.0);
      last_progress = p;
      const std::string set = e.data.value("set", "");
      EXPECT_TRUE(set == "high" || set == "low") << set;
      // One set after the other, in the order the stage runs them.
      if (first_set.empty()) first_set = set;
      if (set != first_set) second_seen = true;
      if (second_seen) {
        EXPECT_NE(set, first_set) << "the first set came back after the second began";
      }
    } else if (e.name == "scan" && e.data.value("id", "") == id) {
      const std::string state = e.data.value("state", "");
      if (state == "done" || state == "failed") done_state = state;
    } else if (e.name == "error") {
      ADD_FAILURE() << "error event: " << e.data.dump();
    }
  }
  EXPECT_TRUE(progress_seen);
  EXPECT_EQ(frames_total, 10);
  EXPECT_EQ(last_frame, frames_total);
  EXPECT_DOUBLE_EQ(last_progress, 1.0);
  EXPECT_TRUE(second_seen);
  EXPECT_EQ(done_state, "done");
  // The idle state may come after the scan event the wait stopped on.
  if (!idle_after) {
    EXPECT_TRUE(waitIdle(client));
  }
  daemon.stop();
}

// The value of the metric line `name{labels} value` (or `name value`).
double metric(const std::string& text, const std::string& series) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(series + " ", 0) == 0) return std::stod(line.substr(series.size() + 1));
  }
  return NAN;
}

TEST(DaemonMetrics, CountScansFramesAndRequests) {
  QuickDaemon daemon;
  const HttpClient& client = daemon.client();
  for (int i = 0; i < 2; ++i) {
    const std::string id = startScan(client, {{"frames", 5}, {"save_bundle", false}});
    ASSERT_FALSE(id.empty());
    ASSERT_EQ(finishScan(client, id).value("state", ""), "done");
  }
  EXPECT_EQ(client.postJson("/api/v1/scans", {{"bogus", 1}}).status, 400);
  const auto r = client.get("/metrics");
  ASSERT_EQ(r.status, 200) << r.describe();
  EXPECT_EQ(r.header("content-type").rfind("text/plain", 0), 0u) << r.header("content-type");
  EXPECT_NE(r.header("content-type").find("version=0.0.4"), std::string::npos)
      << r.header("content-type");
  std::cout << "[daemon e2e] /metrics:\n" << r.body.substr(0, 1500) << "\n";
  EXPECT_EQ(metric(r.body, "cylscan_scans_total{result=\"done\"}"), 2.0);
  EXPECT_EQ(metric(r.body, "cylscan_scans_total{result=\"failed\"}"), 0.0);
  EXPECT_GE(metric(r.body, "cylscan_frames_total"), 20.0);
  EXPECT_EQ(metric(r.body, "cylscan_scan_duration_seconds_count"), 2.0);
  // The last scan ran on a homed head: its time went to travel and the sets,
  // none to homing or to seeking home again.
  EXPECT_GT(metric(r.body, "cylscan_last_scan_board_seconds{part=\"sets\"}"), 0.0);
  EXPECT_GT(metric(r.body, "cylscan_last_scan_board_seconds{part=\"travel\"}"), 0.0);
  EXPECT_EQ(metric(r.body, "cylscan_last_scan_board_seconds{part=\"step_check\"}"), 0.0);
  EXPECT_GT(metric(r.body, "cylscan_peak_resident_bytes"), 1e6);
  EXPECT_GE(metric(r.body, "cylscan_http_requests_total{code=\"202\"}"), 2.0);
  EXPECT_GE(metric(r.body, "cylscan_http_requests_total{code=\"400\"}"), 1.0);
  daemon.stop();
}

}  // namespace
}  // namespace cylscan::test
