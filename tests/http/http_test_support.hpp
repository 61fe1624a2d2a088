// SPDX-License-Identifier: Apache-2.0
// Test support of the HTTP layer's tests: a scripted HeadService (the HTTP
// layer is tested alone; the real service is tested end to end in
// tests/daemon_e2e), a libcurl client and raw sockets for the requests no
// well-behaved client sends.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <curl/curl.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "firmware/daemon/head_service.hpp"
#include "firmware/http/http_api.hpp"

namespace cylscan::test_support {

using nlohmann::json;

// An EventStream on a queue the FakeService fills.
struct FakeQueue {
  std::mutex mutex;
  std::condition_variable cv;
  std::deque<firmware::HeadEvent> events;
  bool closed = false;
};

class FakeStream : public firmware::EventStream {
 public:
  explicit FakeStream(std::shared_ptr<FakeQueue> q) : q_(std::move(q)) {}
  std::optional<firmware::HeadEvent> next(std::chrono::milliseconds timeout) override {
    std::unique_lock lock(q_->mutex);
    q_->cv.wait_for(lock, timeout, [&] { return !q_->events.empty() || q_->closed; });
    if (q_->events.empty()) return std::nullopt;
    auto e = std::move(q_->events.front());
    q_->events.pop_front();
    return e;
  }
  bool closed() const override {
    std::lock_guard lock(q_->mutex);
    return q_->closed && q_->events.empty();
  }
  std::uint64_t dropped() const override { return 0; }

 private:
  std::shared_ptr<FakeQueue> q_;
};

// A live view the test feeds: pictures pushed, or an end with its status.
struct FakeLiveFeed {
  std::mutex mutex;
  std::condition_variable cv;
  std::deque<firmware::LiveFrame> frames;
  std::string end_reason;
  int end_status = 0;
};

class FakeLive : public firmware::LiveStream {
 public:
  explicit FakeLive(std::shared_ptr<FakeLiveFeed> feed) : feed_(std::move(feed)) {}
  std::optional<firmware::LiveFrame> next(std::chrono::milliseconds timeout) override {
    std::unique_lock lock(feed_->mutex);
    feed_->cv.wait_for(lock, timeout,
                       [&] { return !feed_->frames.empty() || !feed_->end_reason.empty(); });
    if (feed_->frames.empty()) return std::nullopt;
    auto frame = std::move(feed_->frames.front());
    feed_->frames.pop_front();
    return frame;
  }
  bool ended() const override {
    std::lock_guard lock(feed_->mutex);
    return !feed_->end_reason.empty() && feed_->frames.empty();
  }
  std::string endReason() const override {
    std::lock_guard lock(feed_->mutex);
    return feed_->end_reason;
  }
  int endStatus() const override {
    std::lock_guard lock(feed_->mutex);
    return feed_->end_status;
  }

 private:
  std::shared_ptr<FakeLiveFeed> feed_;
};

// Scripted answers; every call is recorded so a test can tell what reached
// the service (and what did not).
class FakeService : public firmware::HeadService {
 public:
  mutable std::mutex mutex;
  json status_json = {{"state", "idle"}, {"board", "sim"}, {"version", "0.1.0"}};
  std::map<std::string, json> scans;  // id → scan object
  std::map<std::string, std::map<std::string, std::filesystem::path>> files;
  std::map<std::string, std::filesystem::path> calibration_files;
  std::optional<firmware::ServiceError> start_error, delete_error, install_error;
  std::string next_id = "20261201-160102-3f9a";
  bool initial_event = true;     // subscribe() queues a "state" event first
  bool fail_internally = false;  // listScans() throws a plain exception
  std::string metrics =
      "# TYPE cylscan_scans_total counter\ncylscan_scans_total{result=\"done\"} 3\n";

  // What was asked.
  mutable std::vector<std::string> lookups;  // ids passed to scan()/scanFile()/deleteScan()
  int start_calls = 0, delete_calls = 0, install_calls = 0, head_installs = 0;
  json last_options;
  std::string last_camera, last_bytes, last_head;
  json cameras_json = json::array();
  json checks_json = json::array();
  json last_check;
  std::optional<json> session_json;
  json last_session_body;
  json board_reply = json{{"index", 0}, {"found", {{"main", true}, {"aux", true}}}};
  json last_fringe_body;
  json fringe_reply = json{{"frames", 8}, {"cameras", json::array()}};
  std::map<std::string, std::string> fringe_pictures;
  std::optional<firmware::ServiceError> session_error;
  bool hold_board = false;  // the board capture's answer waits for board_promise
  std::shared_ptr<std::promise<json>> board_promise;
  int board_captures = 0;
  // The promise of the n-th board capture (from 1), once it was asked for.
  std::shared_ptr<std::promise<json>> heldBoard(int n) {
    std::lock_guard lock(mutex);
    return board_captures >= n ? board_promise : nullptr;
  }
  json last_controls;
  std::optional<firmware::ServiceError> camera_error;
  std::vector<firmware::LiveViewRequest> live_requests;

  json status() const override {
    std::lock_guard lock(mutex);
    return status_json;
  }
  json system() const override { return {{"version", "0.0.0-test"}, {"slot", "b"}}; }
  std::string startScan(const json& options) override {
    std::lock_guard lock(mutex);
    ++start_calls;
    last_options = options;
    if (start_error) throw *start_error;
    scans[next_id] = json{{"id", next_id}, {"state", "queued"}};
    return next_id;
  }
  json listScans() const override {
    std::lock_guard lock(mutex);
    if (fail_internally) throw std::runtime_error("scan index unreadable");
    json list = json::array();
    for (auto it = scans.rbegin(); it != scans.rend(); ++it)
      list.push_back(it->second);
    return list;
  }
  std::optional<json> scan(std::string_view id) const override {
    std::lock_guard lock(mutex);
    lookups.emplace_back(id);
    const auto it = scans.find(std::string(id));
    if (it == scans.end()) return std::nullopt;
    return it->second;
  }
  std::optional<std::filesystem::path> scanFile(std::string_view id,
                                                std::string_view name) const override {
    std::lock_guard lock(mutex);
    lookups.emplace_back(id);
    const auto s = files.find(std::string(id));
    if (s == files.end()) return std::nullopt;
    const auto f = s->second.find(std::string(name));
    if (f == s->second.end()) return std::nullopt;
    return f->second;
  }
  bool deleteScan(std::string_view id) override {
    std::lock_guard lock(mutex);
    ++delete_calls;
    lookups.emplace_back(id);
    if (delete_error) throw *delete_error;
    return scans.erase(std::string(id)) > 0;
  }
  json installCalibration(std::string_view camera, std::string_view bytes) override {
    std::lock_guard lock(mutex);
    ++install_calls;
    last_camera = camera;
    last_bytes = bytes;
    if (install_error) throw *install_error;
    return json{{"installed", true}, {"bytes", bytes.size()}};
  }
  json installHead(std::string_view text) override {
    std::lock_guard lock(mutex);
    ++head_installs;
    last_head = text;
    return json{{"format", "cylscan-head-1"}};
  }
  json calibrationInfo(std::string_view camera) const override {
    return json{{"installed", false}, {"camera", std::string(camera)}};
  }
  std::optional<std::filesystem::path> calibrationFile(std::string_view camera) const override {
    std::lock_guard lock(mutex);
    const auto it = calibration_files.find(std::string(camera));
    if (it == calibration_files.end()) return std::nullopt;
    return it->second;
  }
  std::unique_ptr<firmware::EventStream> subscribe() override {
    auto q = std::make_shared<FakeQueue>();
    {
      std::lock_guard lock(mutex);
      queues_.push_back(q);
    }
    if (initial_event) publishTo(*q, ++seq_, "state", json{{"state", "idle"}, {"scan", nullptr}});
    return std::make_unique<FakeStream>(q);
  }
  std::string metricsText() const override {
    std::lock_guard lock(mutex);
    return metrics;
  }
  std::string startCheck(const json& request) override {
    std::lock_guard lock(mutex);
    last_check = request;
    if (start_error) throw *start_error;
    checks_json.insert(checks_json.begin(), json{{"id", next_id}, {"state", "queued"}});
    return next_id;
  }
  json listChecks() const override {
    std::lock_guard lock(mutex);
    return checks_json;
  }
  // The calibration session: a board capture answers with board_reply, or
  // throws session_error (both then apply to every session call).
  json startSession(const json& body) override {
    std::lock_guard lock(mutex);
    last_session_body = body;
    if (session_error) throw *session_error;
    session_json = json{{"state", "capturing"},
                        {"boards", json::array()},
                        {"planes", json::array()},
                        {"progress", 0}};
    return *session_json;
  }
  std::optional<json> session() const override {
    std::lock_guard lock(mutex);
    return session_json;
  }
  std::future<json> captureBoard(const json& body) override {
    std::lock_guard lock(mutex);
    last_session_body = body;
    if (session_error) throw *session_error;
    board_promise = std::make_shared<std::promise<json>>();
    ++board_captures;
    if (!hold_board) board_promise->set_value(board_reply);
    return board_promise->get_future();
  }
  // The fringe check answers with fringe_reply, or throws camera_error;
  // its pictures are fringe_pictures by camera (404 for any other).
  std::future<json> fringeCheck(const json& body) override {
    std::lock_guard lock(mutex);
    last_fringe_body = body;
    if (camera_error) throw *camera_error;
    std::promise<json> promise;
    promise.set_value(fringe_reply);
    return promise.get_future();
  }
  std::string fringePicture(std::string_view camera) const override {
    std::lock_guard lock(mutex);
    const auto it = fringe_pictures.find(std::string(camera));
    if (it == fringe_pictures.end()) throw firmware::ServiceError(404, "no fringe check");
    return it->second;
  }
  json capturePlane(const json& body) override {
    std::lock_guard lock(mutex);
    last_session_body = body;
    if (session_error) throw *session_error;
    return {{"index", 0}};
  }
  void solveSession() override {
    std::lock_guard lock(mutex);
    if (session_error) throw *session_error;
  }
  json installSession() override {
    std::lock_guard lock(mutex);
    if (session_error) throw *session_error;
    return {{"installed", true}};
  }
  json rollbackCalibration() override {
    std::lock_guard lock(mutex);
    if (session_error) throw *session_error;
    return {{"installed", true}};
  }
  json cameras() const override {
    std::lock_guard lock(mutex);
    return cameras_json;
  }
  json setCameraControls(std::string_view camera, const json& controls) override {
    std::lock_guard lock(mutex);
    last_camera = camera;
    last_controls = controls;
    if (camera_error) throw *camera_error;
    return json{{"name", std::string(camera)}, {"controls", controls}};
  }
  std::unique_ptr<firmware::LiveStream> openLiveView(
      const firmware::LiveViewRequest& request) override {
    std::lock_guard lock(mutex);
    live_requests.push_back(request);
    if (camera_error) throw *camera_error;
    auto feed = std::make_shared<FakeLiveFeed>();
    feeds_.push_back(feed);
    return std::make_unique<FakeLive>(feed);
  }
  // The live views the HTTP layer still holds.
  std::vector<std::shared_ptr<FakeLiveFeed>> liveFeeds() {
    std::lock_guard lock(mutex);
    std::vector<std::shared_ptr<FakeLiveFeed>> out;
    std::erase_if(feeds_, [](const auto& w) { return w.expired(); });
    for (const auto& w : feeds_) {
      if (auto f = w.lock()) out.push_back(f);
    }
    return out;
  }
  static void pushPicture(FakeLiveFeed& feed, firmware::LiveFrame frame) {
    std::lock_guard lock(feed.mutex);
    feed.frames.push_back(std::move(frame));
    feed.cv.notify_all();
  }
  static void endLive(FakeLiveFeed& feed, int status, std::string reason) {
    std::lock_guard lock(feed.mutex);
    feed.end_status = status;
    feed.end_reason = std::move(reason);
    feed.cv.notify_all();
  }

  // Events for every live subscriber.
  void publish(const std::string& name, const json& data) {
    const std::uint64_t seq = ++seq_;  // one id for every stream
    for (const auto& q : live())
      publishTo(*q, seq, name, data);
  }
  void closeStreams() {
    for (const auto& q : live()) {
      std::lock_guard lock(q->mutex);
      q->closed = true;
      q->cv.notify_all();
    }
  }
  // Streams the HTTP layer still holds.
  std::size_t subscribers() { return live().size(); }

 private:
  std::vector<std::shared_ptr<FakeQueue>> live() {
    std::lock_guard lock(mutex);
    std::vector<std::shared_ptr<FakeQueue>> out;
    std::erase_if(queues_, [](const auto& w) { return w.expired(); });
    for (const auto& w : queues_) {
      // A queue only the service's list refers to has no stream any more.
      if (auto q = w.lock()) out.push_back(q);
    }
    return out;
  }
  static void publishTo(FakeQueue& q, std::uint64_t seq, const std::string& name,
                        const json& data) {
    std::lock_guard lock(q.mutex);
    q.events.push_back(firmware::HeadEvent{seq, name, data});
    q.cv.notify_all();
  }

  std::vector<std::weak_ptr<FakeQueue>> queues_;
  std::vector<std::weak_ptr<FakeLiveFeed>> feeds_;
  std::atomic<std::uint64_t> seq_{0};
};

// Polls `condition` until it holds or `timeout` passes; whether it held.
inline bool eventually(const std::function<bool()>& condition,
                       std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return condition();
}

struct HttpResult {
  long status = 0;
  std::string body;
  std::map<std::string, std::string> headers;  // names in lower case
  std::string header(const std::string& name) const {
    const auto it = headers.find(name);
    return it == headers.end() ? std::string() : it->second;
  }
  json bodyJson() const { return json::parse(body, nullptr, false); }
};

struct RequestOptions {
  std::string body;
  bool has_body = false;
  std::vector<std::string> headers;  // "Name: value"
  std::string interface;             // local address to connect from
  bool path_as_is = false;           // send ".." as written
};

inline RequestOptions withHeader(std::string header) {
  RequestOptions o;
  o.headers.push_back(std::move(header));
  return o;
}

// One request with libcurl; status 0 when the transfer failed.
inline HttpResult curlRequest(const std::string& method, const std::string& url,
                              const RequestOptions& o = {}) {
  HttpResult result;
  CURL* curl = curl_easy_init();
  if (curl == nullptr) return result;
  curl_slist* headers = nullptr;
  for (const auto& h : o.headers)
    headers = curl_slist_append(headers, h.c_str());
  headers = curl_slist_append(headers, "Expect:");
  curl_easy_setopt(curl, CURLOPT_URL, url.c_str());
  curl_easy_setopt(curl, CURLOPT_TIMEOUT_MS, 5000L);
  curl_easy_setopt(curl, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(curl, CURLOPT_HTTPHEADER, headers);
  if (method == "HEAD") {
    curl_easy_setopt(curl, CURLOPT_NOBODY, 1L);
  } else {
    curl_easy_setopt(curl, CURLOPT_CUSTOMREQUEST, method.c_str());
  }
  if (o.has_body || !o.body.empty()) {
    curl_easy_setopt(curl, CURLOPT_POSTFIELDS, o.body.data());
    curl_easy_setopt(curl, CURLOPT_POSTFIELDSIZE_LARGE, static_cast<curl_off_t>(o.body.size()));
  }
  if (!o.interface.empty()) curl_easy_setopt(curl, CURLOPT_INTERFACE, o.interface.c_str());
  if (o.path_as_is) curl_easy_setopt(curl, CURLOPT_PATH_AS_IS, 1L);
  using Sink = std::string;
  curl_easy_setopt(
      curl, CURLOPT_WRITEFUNCTION, +[](char* p, size_t size, size_t n, void* cls) -> size_t {
        static_cast<Sink*>(cls)->append(p, size * n);
        return size * n;
      });
  curl_easy_setopt(curl, CURLOPT_WRITEDATA, &result.body);
  curl_easy_setopt(
      curl, CURLOPT_HEADERFUNCTION, +[](char* p, size_t size, size_t n, void* cls) -> size_t {
        std::string line(p, size * n);
        const auto colon = line.find(':');
        if (colon != std::string::npos) {
          std::string name = line.substr(0, colon);
          for (auto& c : name)
            c = static_cast<char>(std::tolower(c));
          std::string value = line.substr(colon + 1);
          const auto b = value.find_first_not_of(" \t");
          const auto e = value.find_last_not_of(" \t\r\n");
          value = b == std::string::npos ? "" : value.substr(b, e - b + 1);
          (*static_cast<std::map<std::string, std::string>*>(cls))[name] = value;
        }
        return size * n;
      });
  curl_easy_setopt(curl, CURLOPT_HEADERDATA, &result.headers);
  if (curl_easy_perform(curl) == CURLE_OK) {
    curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &result.status);
  }
  curl_slist_free_all(headers);
  curl_easy_cleanup(curl);
  return result;
}

// A plain TCP connection for the requests curl would not send.
class RawSocket {
 public:
  // Connects to `address`:`port` (IPv4 or IPv6 literal); ok() says whether.
  RawSocket(const std::string& address, std::uint16_t port) {
    sockaddr_storage ss{};
    socklen_t len = 0;
    if (address.find(':') != std::string::npos) {
      sockaddr_in6 a{};
      a.sin6_family = AF_INET6;
      a.sin6_port = htons(port);
      inet_pton(AF_INET6, address.c_str(), &a.sin6_addr);
      std::memcpy(&ss, &a, sizeof a);
      len = sizeof a;
    } else {
      sockaddr_in a{};
      a.sin_family = AF_INET;
      a.sin_port = htons(port);
      inet_pton(AF_INET, address.c_str(), &a.sin_addr);
      std::memcpy(&ss, &a, sizeof a);
      len = sizeof a;
    }
    fd_ = ::socket(ss.ss_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ >= 0 && ::connect(fd_, reinterpret_cast<sockaddr*>(&ss), len) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~RawSocket() { close(); }
  RawSocket(const RawSocket&) = delete;
  RawSocket& operator=(const RawSocket&) = delete;

  bool ok() const { return fd_ >= 0; }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  // Whether all of `data` was sent (false once the peer closed).
  bool send(std::string_view data) {
    while (!data.empty()) {
      const ssize_t n = ::send(fd_, data.data(), data.size(), MSG_NOSIGNAL);
      if (n <= 0) return false;
      data.remove_prefix(static_cast<std::size_t>(n));
    }
    return true;
  }
  // Reads until `done(received)` holds, the peer closes or `timeout` passes.
  // `closed()` tells whether the peer closed.
  std::string readUntil(const std::function<bool(const std::string&)>& done,
                        std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!done(received_)) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          end - std::chrono::steady_clock::now());
      if (left.count() <= 0) break;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
      char buf[8192];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        peer_closed_ = true;
        break;
      }
      received_.append(buf, static_cast<std::size_t>(n));
    }
    return received_;
  }
  // Reads until the end of the response head ("\r\n\r\n").
  std::string readHead(std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    return readUntil([](const std::string& s) { return s.find("\r\n\r\n") != std::string::npos; },
                     timeout);
  }
  std::string readAll(std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    return readUntil([](const std::string&) { return false; }, timeout);
  }
  bool closed() const { return peer_closed_; }
  const std::string& received() const { return received_; }

 private:
  int fd_ = -1;
  std::string received_;
  bool peer_closed_ = false;
};

// How many times `what` occurs in `text`.
inline std::size_t countOf(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto p = text.find(what); p != std::string::npos; p = text.find(what, p + 1))
    ++n;
  return n;
}

// The status code of a raw response ("HTTP/1.1 404 Not Found…"), 0 if none.
inline int statusOf(const std::string& response) {
  if (response.rfind("HTTP/1.", 0) != 0 || response.size() < 12) return 0;
  return std::atoi(response.c_str() + 9);
}

// A FakeService behind a real HttpApi on a free port that wants `token`,
// and the requests that carry it.
class TokenApiTest : public ::testing::Test {
 protected:
  explicit TokenApiTest(std::string token) : token_(std::move(token)) {}
  void SetUp() override {
    options.port = 0;
    options.token = token_;
    api = std::make_unique<firmware::HttpApi>(service, options);
  }
  std::string url(const std::string& path) const {
    return "http://127.0.0.1:" + std::to_string(api->port()) + path;
  }
  std::string authHeader() const { return "Authorization: Bearer " + token_; }
  // With the token and, when given, a JSON body.
  RequestOptions authed(std::string body = {}) const {
    RequestOptions o = withHeader(authHeader());
    if (!body.empty()) {
      o.body = std::move(body);
      o.has_body = true;
      o.headers.emplace_back("Content-Type: application/json");
    }
    return o;
  }

  FakeService service;
  firmware::HttpOptions options;
  std::unique_ptr<firmware::HttpApi> api;

 private:
  std::string token_;
};

}  // namespace cylscan::test_support
