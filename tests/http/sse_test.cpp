// SPDX-License-Identifier: Apache-2.0
// GET /api/v1/events: events in order with ids, keepalives, dropped
// clients, the cap on streams, many idle streams, and the end at shutdown.
#include <dirent.h>

#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "firmware/http/http_api.hpp"
#include "tests/http/http_test_support.hpp"

namespace cylscan::firmware {
namespace {

using nlohmann::json;
using test_support::countOf;
using test_support::curlRequest;
using test_support::eventually;
using test_support::FakeService;
using test_support::RawSocket;
using test_support::statusOf;

constexpr const char* kToken = "sse-token-0123456789";
const std::string kEventsRequest = std::string("GET /api/v1/events HTTP/1.1\r\nHost: x\r\n") +
                                   "Authorization: Bearer " + kToken + "\r\n\r\n";

struct Event {
  std::string id, name, data;
};

// The events in a raw chunked SSE response (chunk framing lines are not
// "id:"/"event:"/"data:" lines, so they are skipped).
std::vector<Event> parseEvents(const std::string& text) {
  std::vector<Event> events;
  Event e;
  std::size_t pos = text.find("\r\n\r\n");
  pos = pos == std::string::npos ? 0 : pos + 4;
  while (pos < text.size()) {
    auto end = text.find('\n', pos);
    if (end == std::string::npos) break;
    std::string line = text.substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    pos = end + 1;
    if (line.rfind("id: ", 0) == 0) e.id = line.substr(4);
    if (line.rfind("event: ", 0) == 0) e.name = line.substr(7);
    if (line.rfind("data: ", 0) == 0) {
      e.data = line.substr(6);
      events.push_back(e);
      e = {};
    }
  }
  return events;
}

std::size_t threadCount() {
  std::size_t n = 0;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
    (void)entry;
    ++n;
  }
  return n;
}

class SseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    options.port = 0;
    options.token = kToken;
    options.sse_keepalive = std::chrono::milliseconds(200);
  }
  void start() { api = std::make_unique<HttpApi>(service, options); }
  std::unique_ptr<RawSocket> openStream() {
    auto s = std::make_unique<RawSocket>("127.0.0.1", api->port());
    EXPECT_TRUE(s->ok());
    s->send(kEventsRequest);
    return s;
  }
  long sseClientsGauge() {
    const auto r =
        curlRequest("GET", "http://127.0.0.1:" + std::to_string(api->port()) + "/metrics",
                    test_support::withHeader(std::string("Authorization: Bearer ") + kToken));
    const auto p = r.body.find("\ncylscan_sse_clients ");
    return p == std::string::npos ? -1 : std::stol(r.body.substr(p + 21));
  }

  FakeService service;
  HttpOptions options;
  std::unique_ptr<HttpApi> api;
};

TEST_F(SseTest, EventsInOrderWithIds) {
  options.sse_keepalive = std::chrono::seconds(60);
  start();
  auto s = openStream();
  const std::string head = s->readHead();
  EXPECT_EQ(statusOf(head), 200) << head;
  EXPECT_NE(head.find("Content-Type: text/event-stream"), std::string::npos) << head;
  ASSERT_TRUE(eventually([&] { return service.subscribers() == 1; }));
  for (int i = 0; i < 5; ++i)
    service.publish("progress", json{{"frames_done", i}});
  service.publish("scan", json{{"id", "x"}, {"text", "two\nlines"}});
  s->readUntil([](const std::string& t) { return parseEvents(t).size() >= 7; });
  const auto events = parseEvents(s->received());
  ASSERT_EQ(events.size(), 7u) << s->received();
  EXPECT_EQ(events[0].name, "state");  // the service's first event
  for (std::size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].id, std::to_string(i + 1));
    const json data = json::parse(events[i].data);  // one line of JSON
    if (i >= 1 && i <= 5) {
      EXPECT_EQ(events[i].name, "progress");
      EXPECT_EQ(data["frames_done"], static_cast<int>(i - 1));
    }
  }
  EXPECT_EQ(events[6].name, "scan");
  EXPECT_EQ(json::parse(events[6].data)["text"], "two\nlines");
}

TEST_F(SseTest, HeadComesAtOnceWithoutEvents) {
  service.initial_event = false;
  options.sse_keepalive = std::chrono::seconds(60);
  start();
  auto s = openStream();
  s->readUntil([](const std::string& t) { return t.find(": cylscan events") != std::string::npos; },
               std::chrono::seconds(3));
  EXPECT_EQ(statusOf(s->received()), 200) << s->received();
  EXPECT_NE(s->received().find("Cache-Control: no-store"), std::string::npos);
  EXPECT_NE(s->received().find(": cylscan events\n\n"), std::string::npos);
}

TEST_F(SseTest, KeepalivesWhileIdle) {
  start();
  auto s = openStream();
  s->readUntil([](const std::string& t) { return countOf(t, ": keepalive\n\n") >= 2; },
               std::chrono::seconds(4));
  EXPECT_GE(countOf(s->received(), ": keepalive\n\n"), 2u) << s->received();
  // Events still come between them.
  service.publish("state", json{{"state", "scanning"}});
  s->readUntil([](const std::string& t) { return parseEvents(t).size() >= 2; });
  EXPECT_EQ(parseEvents(s->received()).size(), 2u);
}

TEST_F(SseTest, ClosedClientIsDropped) {
  start();
  auto s = openStream();
  EXPECT_EQ(statusOf(s->readHead()), 200);
  ASSERT_TRUE(eventually([&] { return service.subscribers() == 1; }));
  EXPECT_EQ(sseClientsGauge(), 1);
  s->close();
  // Noticed at the next writes (keepalives): the subscription ends.
  EXPECT_TRUE(eventually([&] { return service.subscribers() == 0; }));
  EXPECT_EQ(sseClientsGauge(), 0);
}

TEST_F(SseTest, ServiceClosingEndsTheStream) {
  start();
  auto s = openStream();
  EXPECT_EQ(statusOf(s->readHead()), 200);
  ASSERT_TRUE(eventually([&] { return service.subscribers() == 1; }));
  service.closeStreams();
  // The chunked body ends ("0\r\n\r\n") and the stream is released.
  s->readUntil([](const std::string& t) { return t.find("\r\n0\r\n\r\n") != std::string::npos; });
  EXPECT_NE(s->received().find("\r\n0\r\n\r\n"), std::string::npos) << s->received();
  EXPECT_TRUE(eventually([&] { return service.subscribers() == 0; }));
}

TEST_F(SseTest, NeedsTheToken) {
  start();
  RawSocket s("127.0.0.1", api->port());
  s.send("GET /api/v1/events HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(statusOf(s.readHead()), 401);
  EXPECT_EQ(service.subscribers(), 0u);
}

TEST_F(SseTest, TooManyStreamsAre503) {
  options.max_sse_clients = 2;
  start();
  auto a = openStream();
  auto b = openStream();
  EXPECT_EQ(statusOf(a->readHead()), 200);
  EXPECT_EQ(statusOf(b->readHead()), 200);
  auto c = openStream();
  const std::string head =
      c->readUntil([](const std::string& t) { return t.find("}") != std::string::npos; });
  EXPECT_EQ(statusOf(head), 503) << head;
  EXPECT_NE(head.find("too many event streams"), std::string::npos);
  // A place freed is a place again.
  a->close();
  ASSERT_TRUE(eventually([&] { return service.subscribers() == 1; }));
  auto d = openStream();
  EXPECT_EQ(statusOf(d->readHead()), 200);
}

TEST_F(SseTest, ManyIdleStreamsCostNoThreads) {
  constexpr int kClients = 200;
  options.max_sse_clients = 256;
  options.max_connections = 512;
  options.max_connections_per_ip = 300;
  options.sse_keepalive = std::chrono::seconds(60);
  start();
  const std::size_t threads_before = threadCount();
  std::vector<std::unique_ptr<RawSocket>> streams;
  for (int i = 0; i < kClients; ++i)
    streams.push_back(openStream());
  for (auto& s : streams)
    ASSERT_EQ(statusOf(s->readHead()), 200);
  ASSERT_TRUE(eventually([&] { return service.subscribers() == kClients; }));
  EXPECT_EQ(sseClientsGauge(), kClients);
  // The server still answers, and holds the streams without a thread each.
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 20; ++i) {
    const std::string status_url =
        "http://127.0.0.1:" + std::to_string(api->port()) + "/api/v1/status";
    EXPECT_EQ(curlRequest("GET", status_url).status, 200);
  }
  const std::chrono::duration<double, std::milli> took = std::chrono::steady_clock::now() - t0;
  const std::size_t threads = threadCount();
  EXPECT_LT(threads, threads_before + 5);
  // For the record only (no timing assertion): what it cost.
  std::cout << kClients << " idle streams: " << threads << " threads in the process ("
            << threads_before << " before them); 20 status requests took " << took.count()
            << " ms\n";
  // An event reaches every stream.
  service.publish("state", json{{"state", "scanning"}});
  for (auto& s : streams) {
    s->readUntil([](const std::string& t) { return t.find("scanning") != std::string::npos; });
    EXPECT_NE(s->received().find("scanning"), std::string::npos);
  }
  streams.clear();
  EXPECT_TRUE(eventually([&] { return service.subscribers() == 0; }, std::chrono::seconds(10)))
      << service.subscribers();
}

TEST_F(SseTest, ShutdownEndsOpenStreams) {
  options.sse_keepalive = std::chrono::seconds(60);
  start();
  auto s = openStream();
  EXPECT_EQ(statusOf(s->readHead()), 200);
  ASSERT_TRUE(eventually([&] { return service.subscribers() == 1; }));
  api.reset();
  s->readAll(std::chrono::seconds(3));
  EXPECT_TRUE(s->closed());
  EXPECT_EQ(service.subscribers(), 0u);
}

}  // namespace
}  // namespace cylscan::firmware
