// SPDX-License-Identifier: Apache-2.0
#include "firmware/http/http_api.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <condition_variable>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <functional>
#include <future>
#include <iostream>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "common/vocabulary.hpp"
#include "firmware/http/auth.hpp"
#include "firmware/http/files.hpp"
#include "firmware/http/http_metrics.hpp"
#include "firmware/http/router.hpp"

namespace cylscan::firmware {
namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

constexpr std::chrono::milliseconds kPumpTick{50};  // how often event streams are looked at
constexpr std::size_t kSsePendingLimit = 1u << 20;  // unsent bytes per stream
constexpr std::size_t kSseBlockSize = 4096;
// A live view's parts are whole JPEGs: larger blocks, fewer calls.
constexpr std::size_t kLiveBlockSize = 64u << 10;
constexpr std::string_view kLiveBoundary = "cylscanframe";
// How long a snapshot waits for its picture before it is refused.
constexpr std::chrono::seconds kSnapshotTimeout{10};
// How long a checkerboard pair may take (a scan plan's frames in both
// cameras) before the request is answered 503; the capture itself goes on.
constexpr std::chrono::seconds kCaptureTimeout{300};
// A request refused before its body was read: the client may still be
// sending it, and a browser reads the answer only once it has sent it all.
// Closing at once would reset the connection and lose the answer, so the
// rest is read and thrown away for a while (at most this long and this many
// bytes), then the socket is closed.
constexpr std::chrono::seconds kLingerTime{3};
constexpr std::size_t kLingerBytes = 256u << 20;
constexpr std::size_t kLingerBytesPerTick = 8u << 20;

std::string dumpJson(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string errorBody(std::string_view message) {
  return dumpJson(json{{"error", std::string(message)}});
}

// What a handler answers: a body in memory or an open file.
struct Reply {
  int status = 200;
  std::string body;
  std::string content_type = "application/json";
  std::string cache_control = "no-store";
  std::vector<std::pair<std::string, std::string>> headers;
  std::optional<http::OpenFile> file;
};

Reply jsonReply(int status, const json& value) {
  Reply r;
  r.status = status;
  r.body = dumpJson(value);
  return r;
}

Reply errorReply(int status, std::string_view message) {
  Reply r;
  r.status = status;
  r.body = errorBody(message);
  return r;
}

// One request's state across libmicrohttpd's calls of the access handler.
struct Request {
  Clock::time_point start = Clock::now();
  http::Route route;
  std::string method;
  std::string url;
  std::size_t limit = 0;  // body bytes allowed
  std::string body;
  std::optional<Reply> deferred;  // a refusal to answer in the last call
  bool holds_calibration_upload = false;
  // PUT /api/v1/system/update: the body goes to the update's file as it
  // arrives, never into `body`. Destroyed unfinished, the upload is failed.
  std::unique_ptr<UpdateUpload> update;
  bool answered = false;                         // a response is queued
  std::shared_ptr<struct PendingReply> pending;  // suspended until its reply is ready
  bool counted_pending = false;                  // in pending_in_flight
  bool in_begin = false;                         // answering in the first call: the body is unread
  bool linger = false;                           // answered before a body that is still coming
  int fd = -1;                                   // the connection's socket
};

// The socket of a connection answered before its body was read, kept open
// (a duplicate of libmicrohttpd's descriptor) while the rest is drained.
struct Lingering {
  int fd = -1;
  Clock::time_point deadline;
  std::size_t drained = 0;
};

// A request's JSON body: `empty` when there is none (only white space);
// ServiceError 400 when it is not JSON, or not an object.
json bodyObject(const std::string& body, json empty) {
  if (body.find_first_not_of(" \t\r\n") == std::string::npos) return empty;
  json parsed;
  try {
    parsed = json::parse(body);
  } catch (const json::exception& e) {  // parse_error, or out_of_range for 1e400
    throw ServiceError(400, std::string("the body is not valid JSON: ") + e.what());
  }
  if (!parsed.is_object()) throw ServiceError(400, "the body must be a JSON object");
  return parsed;
}

struct SseClient;

// A request suspended until its answer is ready, or the wait times out; the
// pump then sets the reply and resumes it. A snapshot waits for the live
// view's picture (or its end); a checkerboard pair for the head's capture.
struct PendingReply {
  MHD_Connection* connection = nullptr;
  std::unique_ptr<LiveStream> live;  // a snapshot
  std::future<json> answer;          // a capture: its JSON, or its ServiceError
  int answer_status = 201;
  Clock::time_point deadline;
  std::string camera;
  std::mutex mutex;
  std::optional<Reply> reply;
};

}  // namespace

struct ApiServer;

struct ApiServer {
  ApiServer(HeadService& s, HttpOptions o) : service(s), options(std::move(o)) {}

  HeadService& service;
  HttpOptions options;
  http::HttpMetrics metrics;
  std::atomic<bool> calibration_upload{false};  // a PUT /api/v1/calibration is being read
  MHD_Daemon* daemon = nullptr;
  std::uint16_t bound_port = 0;

  // Event streams: registered while their response lives.
  std::mutex sse_mutex;
  std::condition_variable sse_cv;
  std::map<SseClient*, std::shared_ptr<SseClient>> sse_clients;
  std::vector<std::shared_ptr<PendingReply>> pending_replies;  // suspended requests
  std::size_t pending_in_flight = 0;  // suspended or resumed, not yet completed
  std::vector<Lingering> lingering;   // the pump's
  bool stopping = false;
  std::thread pump;

  void log(std::string_view line) const;
  void start();
  void stop();

  MHD_Result access(MHD_Connection* c, const char* url, const char* method, const char* upload_data,
                    std::size_t* upload_size, void** con_cls);
  MHD_Result begin(MHD_Connection* c, const char* url, Request& r);
  MHD_Result beginRequest(MHD_Connection* c, const char* url, Request& r);
  MHD_Result beginUpdate(MHD_Connection* c, Request& r);
  Reply finishUpdate(Request& r);
  MHD_Result answer(MHD_Connection* c, Request& r, Reply reply);
  MHD_Result refuse(MHD_Connection* c, Request& r, Reply reply);
  std::optional<Reply> checkAuth(MHD_Connection* c) const;
  Reply dispatch(MHD_Connection* c, Request& r);
  Reply handle(MHD_Connection* c, Request& r);
  Reply staticFile(const Request& r) const;
  MHD_Result startEvents(MHD_Connection* c, Request& r);
  MHD_Result startLiveView(MHD_Connection* c, Request& r);
  MHD_Result startStream(MHD_Connection* c, Request& r, const std::shared_ptr<SseClient>& client,
                         const char* content_type, std::size_t block_size,
                         const std::function<void(SseClient&)>& open);
  MHD_Result startSnapshot(MHD_Connection* c, Request& r);
  // Suspends the request until the head answers `start`'s future (a
  // checkerboard pair, a fringe check), then answers `status` with it.
  MHD_Result startCapture(MHD_Connection* c, Request& r, int status,
                          const std::function<std::future<json>()>& start);
  MHD_Result suspend(MHD_Connection* c, Request& r, std::shared_ptr<PendingReply> pending);
  void servePending();
  void serveLive(SseClient& client, Clock::time_point now);
  void drainLingering(Clock::time_point now);
  void completed(const Request& r);

  void pumpLoop();
  void dropHungUp(const std::vector<std::shared_ptr<SseClient>>& clients);
  void sseFreed(SseClient* client);
};

namespace {

struct SseClient {
  ApiServer* owner = nullptr;
  MHD_Connection* connection = nullptr;
  int fd = -1;  // the connection's socket, watched for a hang-up while suspended
  std::unique_ptr<EventStream> stream;  // an event stream's source,
  std::unique_ptr<LiveStream> live;     // or a live view's
  bool is_live = false;                 // set before it is registered

  std::mutex mutex;
  std::string pending;  // formatted, not yet handed to libmicrohttpd
  bool suspended = false;
  bool ended = false;  // send what is pending, then end the stream
  Clock::time_point last_output = Clock::now();
  std::uint64_t dropped_seen = 0;
  std::atomic<bool> gone{false};  // the response is freed

  void append(std::string_view text, Clock::time_point now) {
    pending += text;
    last_output = now;
  }
};

std::string formatNumber(double x) {
  std::ostringstream out;
  out.precision(6);
  out << x;
  return out.str();
}

// One part of a multipart/x-mixed-replace live view.
std::string formatPart(const LiveFrame& frame) {
  std::string out = "--" + std::string(kLiveBoundary) + "\r\n";
  out += "Content-Type: image/jpeg\r\n";
  out += "Content-Length: " + std::to_string(frame.jpeg.size()) + "\r\n";
  out += "X-Cylscan-Sequence: " + std::to_string(frame.sequence) + "\r\n";
  out += "X-Cylscan-Focus: " + formatNumber(frame.focus) + "\r\n";
  out += "X-Cylscan-Saturated: " + formatNumber(frame.saturated) + "\r\n\r\n";
  out += frame.jpeg;
  out += "\r\n";
  return out;
}

std::string formatEvent(const HeadEvent& e) {
  std::string out = "id: " + std::to_string(e.seq) + "\n";
  out += "event: " + e.name + "\n";
  out += "data: " + dumpJson(e.data) + "\n\n";
  return out;
}

// libmicrohttpd asks for more of an event stream: what is pending, or the
// end, or nothing yet: then the connection is suspended (it costs no thread
// and is not polled) until the pump has something and resumes it.
ssize_t sseRead(void* cls, std::uint64_t /*pos*/, char* buf, std::size_t max) {
  auto* client = static_cast<SseClient*>(cls);
  std::lock_guard lock(client->mutex);
  if (!client->pending.empty()) {
    const std::size_t n = std::min(max, client->pending.size());
    // A chunk of the byte stream, not a C string: no terminator wanted.
    // NOLINTNEXTLINE(bugprone-not-null-terminated-result)
    std::memcpy(buf, client->pending.data(), n);
    client->pending.erase(0, n);
    return static_cast<ssize_t>(n);
  }
  if (client->ended) return MHD_CONTENT_READER_END_OF_STREAM;
  client->suspended = true;
  MHD_suspend_connection(client->connection);
  return 0;
}

void sseFree(void* cls) {
  auto* client = static_cast<SseClient*>(cls);
  client->gone = true;
  client->owner->sseFreed(client);
}

MHD_Result accessTrampoline(void* cls, MHD_Connection* c, const char* url, const char* method,
                            const char* /*version*/, const char* upload_data,
                            std::size_t* upload_size, void** con_cls) {
  return static_cast<ApiServer*>(cls)->access(c, url, method, upload_data, upload_size, con_cls);
}

void completedTrampoline(void* cls, MHD_Connection* /*c*/, void** con_cls,
                         MHD_RequestTerminationCode /*toe*/) {
  if (*con_cls == nullptr) return;
  std::unique_ptr<Request> request(static_cast<Request*>(*con_cls));
  *con_cls = nullptr;
  static_cast<ApiServer*>(cls)->completed(*request);
}

void mhdLogger(void* cls, const char* fmt, va_list ap) {
  char line[512];
  std::vsnprintf(line, sizeof line, fmt, ap);
  std::string_view text(line);
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r'))
    text.remove_suffix(1);
  // A client that goes away is normal (an event stream ends so): not an error.
  for (const std::string_view normal :
       {"forcibly closed by remote peer", "no longer available for sending",
        "Connection reset by peer", "Broken pipe"}) {
    if (text.find(normal) != std::string_view::npos) return;
  }
  static_cast<const ApiServer*>(cls)->log(text);
}

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Percent-decoding of paths and query arguments that leaves encoded
// separators, backslashes and control characters (%2F, %5C, %00, …) as they
// are: they never become a '/' or a NUL, and the router refuses a path with
// a '%' left in it.
std::size_t unescape(void* /*cls*/, MHD_Connection* /*c*/, char* s) {
  char* out = s;
  for (const char* in = s; *in != '\0';) {
    if (in[0] == '%' && in[1] != '\0' && in[2] != '\0') {
      const int hi = hexValue(in[1]);
      const int lo = hexValue(in[2]);
      if (hi >= 0 && lo >= 0) {
        const int v = hi * 16 + lo;
        if (v >= 0x20 && v != 0x7f && v != '/' && v != '\\') {
          *out++ = static_cast<char>(v);
          in += 3;
          continue;
        }
      }
    }
    *out++ = *in++;
  }
  *out = '\0';
  return static_cast<std::size_t>(out - s);
}

MHD_Result sumValue(void* cls, MHD_ValueKind /*kind*/, const char* key, const char* value) {
  auto* total = static_cast<std::size_t*>(cls);
  *total += std::strlen(key) + (value != nullptr ? std::strlen(value) : 0) + 4;
  return MHD_YES;
}

// `?overlay=saturation`: true; no overlay: false; anything else: nullopt.
std::optional<bool> saturationOverlayAsked(MHD_Connection* c) {
  const char* v = MHD_lookup_connection_value(c, MHD_GET_ARGUMENT_KIND, "overlay");
  if (v == nullptr) return false;
  if (std::string_view(v) == "saturation") return true;
  return std::nullopt;
}

const char* headerValue(MHD_Connection* c, const char* name) {
  return MHD_lookup_connection_value(c, MHD_HEADER_KIND, name);
}

}  // namespace

void ApiServer::log(std::string_view line) const {
  if (options.log) {
    options.log(line);
  } else {
    std::cerr << "cylscand: http: " << line << '\n';
  }
}

void ApiServer::start() {
  sockaddr_storage storage{};
  // poll, not epoll: libmicrohttpd 0.9.75's edge-triggered epoll can miss a
  // client's FIN that arrives with the last body bytes, and the request is
  // then held until the connection timeout (a cut-off update upload kept the
  // update busy for 60 s in about one run in four). The connections are few.
  unsigned flags = MHD_USE_POLL_INTERNAL_THREAD | MHD_ALLOW_SUSPEND_RESUME | MHD_USE_ERROR_LOG;
  if (options.address.find(':') != std::string::npos) {
    sockaddr_in6 v6{};
    v6.sin6_family = AF_INET6;
    v6.sin6_port = htons(options.port);
    if (inet_pton(AF_INET6, options.address.c_str(), &v6.sin6_addr) != 1) {
      throw std::runtime_error("http: '" + options.address + "' is not an IPv6 address");
    }
    std::memcpy(&storage, &v6, sizeof v6);
    flags |= MHD_USE_IPv6;
  } else {
    sockaddr_in v4{};
    v4.sin_family = AF_INET;
    v4.sin_port = htons(options.port);
    if (inet_pton(AF_INET, options.address.c_str(), &v4.sin_addr) != 1) {
      throw std::runtime_error("http: '" + options.address + "' is not an IPv4 address");
    }
    std::memcpy(&storage, &v4, sizeof v4);
  }
  // The pool must hold the largest request head we answer ourselves (431
  // past max_header_bytes) plus the response's headers and a read buffer.
  const std::size_t memory =
      std::max<std::size_t>(32u << 10, 2 * options.max_header_bytes + (16u << 10));
  std::vector<MHD_OptionItem> items;
  items.push_back({MHD_OPTION_SOCK_ADDR, 0, &storage});
  items.push_back({MHD_OPTION_CONNECTION_LIMIT, options.max_connections, nullptr});
  if (options.max_connections_per_ip > 0) {
    items.push_back({MHD_OPTION_PER_IP_CONNECTION_LIMIT, options.max_connections_per_ip, nullptr});
  }
  items.push_back({MHD_OPTION_CONNECTION_TIMEOUT,
                   static_cast<intptr_t>(options.connection_timeout.count()), nullptr});
  items.push_back({MHD_OPTION_CONNECTION_MEMORY_LIMIT, static_cast<intptr_t>(memory), nullptr});
  if (options.worker_threads > 1) {
    items.push_back({MHD_OPTION_THREAD_POOL_SIZE, options.worker_threads, nullptr});
  }
  items.push_back({MHD_OPTION_END, 0, nullptr});

  // The logger first: libmicrohttpd logs the options after it its own way.
  daemon = MHD_start_daemon(flags, options.port, nullptr, nullptr, &accessTrampoline, this,
                            MHD_OPTION_EXTERNAL_LOGGER, &mhdLogger, this, MHD_OPTION_ARRAY,
                            items.data(), MHD_OPTION_NOTIFY_COMPLETED, &completedTrampoline, this,
                            MHD_OPTION_UNESCAPE_CALLBACK, &unescape, this, MHD_OPTION_END);
  if (daemon == nullptr) {
    throw std::runtime_error("http: cannot listen on " + options.address + " port " +
                             std::to_string(options.port) + ": " +
                             std::error_code(errno, std::generic_category()).message());
  }
  const MHD_DaemonInfo* info = MHD_get_daemon_info(daemon, MHD_DAEMON_INFO_BIND_PORT);
  bound_port = info != nullptr ? info->port : options.port;
  pump = std::thread([this] { pumpLoop(); });
}

void ApiServer::stop() {
  std::vector<std::shared_ptr<SseClient>> clients;
  {
    std::lock_guard lock(sse_mutex);
    stopping = true;
    for (const auto& [key, client] : sse_clients)
      clients.push_back(client);
  }
  sse_cv.notify_all();
  if (pump.joinable()) pump.join();
  servePending();  // every one is answered 503 now that stopping is set
  // End every stream: a suspended one is resumed and its reader answers the
  // end (libmicrohttpd must not be stopped with suspended connections).
  for (const auto& client : clients) {
    std::lock_guard lock(client->mutex);
    client->ended = true;
    if (client->suspended && !client->gone) {
      client->suspended = false;
      MHD_resume_connection(client->connection);
    }
  }
  clients.clear();
  {
    // Bounded: a client that reads nothing must not hold the shutdown.
    std::unique_lock lock(sse_mutex);
    sse_cv.wait_for(lock, std::chrono::seconds(2),
                    [this] { return sse_clients.empty() && pending_in_flight == 0; });
  }
  if (daemon != nullptr) MHD_stop_daemon(daemon);
  daemon = nullptr;
  std::lock_guard lock(sse_mutex);
  sse_clients.clear();
  for (const Lingering& l : lingering)
    ::close(l.fd);
  lingering.clear();
}

MHD_Result ApiServer::access(MHD_Connection* c, const char* url, const char* method,
                             const char* upload_data, std::size_t* upload_size, void** con_cls) {
  if (*con_cls == nullptr) {
    auto request = std::make_unique<Request>();
    request->method = method;
    request->url = url;
    Request& r = *request;
    *con_cls = request.release();  // owned again in completedTrampoline
    return begin(c, url, r);
  }
  Request& r = *static_cast<Request*>(*con_cls);
  if (*upload_size != 0) {
    if (r.answered) {
      *upload_size = 0;
      return MHD_YES;
    }
    if (r.update) {
      r.update->write(std::string_view(upload_data, *upload_size));
      *upload_size = 0;
      return MHD_YES;
    }
    if (r.body.size() + *upload_size > r.limit) {
      // Cannot happen with the Content-Length checked in begin() (and no
      // chunked bodies); should it, the connection is closed at once, the
      // rest unread (libmicrohttpd 0.9.75 takes no response during an upload).
      log("request body past its limit during the upload: connection closed");
      return MHD_NO;
    }
    r.body.append(upload_data, *upload_size);
    *upload_size = 0;
    return MHD_YES;
  }
  if (r.answered) return MHD_YES;
  if (r.deferred) return answer(c, r, std::move(*r.deferred));
  if (r.pending) {  // resumed by the pump with its reply
    std::optional<Reply> reply;
    {
      std::lock_guard lock(r.pending->mutex);
      reply = std::move(r.pending->reply);
    }
    r.pending.reset();
    return answer(c, r, reply ? std::move(*reply) : errorReply(503, "no picture was taken"));
  }
  if (r.route.endpoint == http::Endpoint::Events && r.method == "GET") return startEvents(c, r);
  if (r.route.endpoint == http::Endpoint::CameraStream && r.method == "GET")
    return startLiveView(c, r);
  if (r.route.endpoint == http::Endpoint::CameraSnapshot) return startSnapshot(c, r);
  if (r.route.endpoint == http::Endpoint::CalibrationBoards) {
    return startCapture(c, r, 201,
                        [&] { return service.captureBoard(bodyObject(r.body, json::object())); });
  }
  if (r.route.endpoint == http::Endpoint::SystemUpdate) return answer(c, r, finishUpdate(r));
  if (r.route.endpoint == http::Endpoint::FringeCheck) {
    return startCapture(c, r, 200,
                        [&] { return service.fringeCheck(bodyObject(r.body, json::object())); });
  }
  return answer(c, r, dispatch(c, r));
}

std::optional<Reply> ApiServer::checkAuth(MHD_Connection* c) const {
  if (options.token.empty()) return std::nullopt;
  const auto unauthorized = [](std::string_view message) {
    Reply r = errorReply(401, message);
    r.headers.emplace_back(MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer");
    return r;
  };
  if (MHD_lookup_connection_value(c, MHD_GET_ARGUMENT_KIND, "token") != nullptr ||
      MHD_lookup_connection_value(c, MHD_GET_ARGUMENT_KIND, "access_token") != nullptr) {
    return unauthorized(
        "a token in the query string is never accepted: send 'Authorization: Bearer TOKEN'");
  }
  if (options.allow_loopback_without_token) {
    const MHD_ConnectionInfo* info = MHD_get_connection_info(c, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
    if (info != nullptr && http::isLoopbackPeer(info->client_addr)) return std::nullopt;
  }
  const char* header = headerValue(c, MHD_HTTP_HEADER_AUTHORIZATION);
  if (header == nullptr) return unauthorized("missing 'Authorization: Bearer TOKEN' header");
  const auto token = http::bearerToken(header);
  if (!token) return unauthorized("the Authorization header is not 'Bearer TOKEN'");
  if (!http::tokenEquals(options.token, *token)) return unauthorized("wrong bearer token");
  return std::nullopt;
}

// Refusals found in the head are answered at once when a body follows (it
// is then never read: libmicrohttpd closes the connection after the answer);
// else with the rest, in the last call, where the connection can be kept
// alive (an answer queued in the first call always closes it).
MHD_Result ApiServer::refuse(MHD_Connection* c, Request& r, Reply reply) {
  const char* length = headerValue(c, MHD_HTTP_HEADER_CONTENT_LENGTH);
  const bool body_follows = headerValue(c, MHD_HTTP_HEADER_TRANSFER_ENCODING) != nullptr ||
                            (length != nullptr && std::strcmp(length, "0") != 0);
  if (body_follows) return answer(c, r, std::move(reply));
  r.deferred = std::move(reply);
  return MHD_YES;
}

MHD_Result ApiServer::begin(MHD_Connection* c, const char* url, Request& r) {
  if (const MHD_ConnectionInfo* info =
          MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD)) {
    r.fd = info->connect_fd;
  }
  r.in_begin = true;
  const MHD_Result result = beginRequest(c, url, r);
  r.in_begin = false;
  return result;
}

MHD_Result ApiServer::beginRequest(MHD_Connection* c, const char* url, Request& r) {
  // Request line and headers: libmicrohttpd answers itself when they do not
  // fit its per-connection memory; below that, max_header_bytes applies.
  std::size_t head = std::strlen(url) + r.method.size() + 12;
  MHD_get_connection_values(c, MHD_HEADER_KIND, &sumValue, &head);
  MHD_get_connection_values(c, MHD_GET_ARGUMENT_KIND, &sumValue, &head);
  if (head > options.max_header_bytes) {
    return refuse(c, r,
                  errorReply(431, "request line and headers larger than " +
                                      std::to_string(options.max_header_bytes) + " bytes"));
  }
  r.route = http::route(r.method, url);
  if (r.route.status != 0) {
    Reply reply = errorReply(r.route.status, r.route.error);
    if (r.route.status == 405) reply.headers.emplace_back(MHD_HTTP_HEADER_ALLOW, r.route.allow);
    return refuse(c, r, std::move(reply));
  }
  if (http::needsToken(r.route.endpoint)) {
    if (auto refused = checkAuth(c)) return refuse(c, r, std::move(*refused));
  }
  if (r.route.param_status != 0) {
    return refuse(c, r, errorReply(r.route.param_status, r.route.error));
  }
  if (r.route.endpoint == http::Endpoint::SystemUpdate) return beginUpdate(c, r);
  // By the endpoint, never by the limit: the two limits may be equal.
  const bool calibration_upload_request =
      r.route.endpoint == http::Endpoint::Calibration && r.method == "PUT";
  r.limit = calibration_upload_request ? options.max_calibration_bytes : options.max_json_bytes;
  // The limit is checked before any byte of the body is read, so the size
  // must be known: a chunked body (no Content-Length) is refused with 411.
  if (headerValue(c, MHD_HTTP_HEADER_TRANSFER_ENCODING) != nullptr) {
    return answer(c, r,
                  errorReply(411, "send the body with a Content-Length (no chunked uploads)"));
  }
  if (const char* length = headerValue(c, MHD_HTTP_HEADER_CONTENT_LENGTH)) {
    std::uint64_t n = 0;
    const auto end = length + std::strlen(length);
    const auto [ptr, ec] = std::from_chars(length, end, n);
    if (ec != std::errc{} || ptr != end) {
      return answer(c, r, errorReply(400, "Content-Length is not a number"));
    }
    if (n > r.limit) {
      return answer(
          c, r,
          errorReply(413, "request body of " + std::to_string(n) + " bytes is larger than " +
                              std::to_string(r.limit) + " bytes"));
    }
    // Memory grows with what arrives, not with what is announced.
    r.body.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(n, 1u << 20)));
  }
  if (calibration_upload_request) {
    // One calibration upload at a time: each may hold max_calibration_bytes.
    if (calibration_upload.exchange(true)) {
      return answer(c, r, errorReply(409, "another calibration upload is in progress"));
    }
    r.holds_calibration_upload = true;
  }
  return MHD_YES;  // the body (if any) comes in the next calls, the answer in the last
}

// A bundle is streamed to the service's file, so its size is bounded by the
// service (update.max_bundle_bytes, the free space), not by r.limit; the
// service refuses before any byte is read, with the rest then drained.
MHD_Result ApiServer::beginUpdate(MHD_Connection* c, Request& r) {
  if (headerValue(c, MHD_HTTP_HEADER_TRANSFER_ENCODING) != nullptr) {
    return answer(c, r,
                  errorReply(411, "send the bundle with a Content-Length (no chunked uploads)"));
  }
  const char* length = headerValue(c, MHD_HTTP_HEADER_CONTENT_LENGTH);
  if (length == nullptr) {
    return refuse(c, r, errorReply(411, "send the bundle with a Content-Length"));
  }
  std::uint64_t n = 0;
  const auto end = length + std::strlen(length);
  const auto [ptr, ec] = std::from_chars(length, end, n);
  if (ec != std::errc{} || ptr != end) {
    return answer(c, r, errorReply(400, "Content-Length is not a number"));
  }
  if (n == 0) return refuse(c, r, errorReply(400, "the body must be a RAUC bundle (it is empty)"));
  const char* type = headerValue(c, MHD_HTTP_HEADER_CONTENT_TYPE);
  if (type != nullptr && std::string_view(type).substr(0, 24) != "application/octet-stream") {
    return answer(
        c, r,
        errorReply(415, "send the bundle as application/octet-stream, not " + std::string(type)));
  }
  try {
    r.update = service.beginUpdate(n);
  } catch (const ServiceError& e) {
    return answer(c, r, errorReply(e.httpStatus(), e.what()));
  } catch (const std::exception& e) {
    log(std::string("internal error starting an update: ") + e.what());
    return answer(c, r, errorReply(500, std::string("internal error: ") + e.what()));
  }
  return MHD_YES;
}

Reply ApiServer::finishUpdate(Request& r) {
  if (!r.update) return errorReply(500, "internal error: no update was started");
  const std::unique_ptr<UpdateUpload> upload = std::move(r.update);
  try {
    return jsonReply(202, upload->finish());
  } catch (const ServiceError& e) {
    return errorReply(e.httpStatus(), e.what());
  } catch (const std::exception& e) {
    log(std::string("internal error installing an update: ") + e.what());
    return errorReply(500, std::string("internal error: ") + e.what());
  }
}

MHD_Result ApiServer::answer(MHD_Connection* c, Request& r, Reply reply) {
  if (r.in_begin) {
    const char* length = headerValue(c, MHD_HTTP_HEADER_CONTENT_LENGTH);
    r.linger = headerValue(c, MHD_HTTP_HEADER_TRANSFER_ENCODING) != nullptr ||
               (length != nullptr && std::strcmp(length, "0") != 0);
  }
  // The upload is over once it is answered: the next upload, sent as soon as
  // the client has this answer, must not find the slot still taken (the
  // completion callback runs only after the client has the answer).
  if (r.holds_calibration_upload) {
    std::string().swap(r.body);
    r.holds_calibration_upload = false;
    calibration_upload = false;
  }
  MHD_Response* response = nullptr;
  if (reply.file) {
    const std::uint64_t size = reply.file->size();
    const int fd = reply.file->release();
    response = MHD_create_response_from_fd64(size, fd);  // closes fd when done
    if (response == nullptr) {
      ::close(fd);
      reply = errorReply(500, "cannot send the file");
    }
  }
  if (response == nullptr) {
    response = MHD_create_response_from_buffer(reply.body.size(), reply.body.data(),
                                               MHD_RESPMEM_MUST_COPY);
  }
  if (response == nullptr) return MHD_NO;
  if (!(reply.status == 204)) {
    MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, reply.content_type.c_str());
  }
  MHD_add_response_header(response, MHD_HTTP_HEADER_CACHE_CONTROL, reply.cache_control.c_str());
  MHD_add_response_header(response, "X-Content-Type-Options", "nosniff");
  for (const auto& [name, value] : reply.headers) {
    MHD_add_response_header(response, name.c_str(), value.c_str());
  }
  const MHD_Result result = MHD_queue_response(c, static_cast<unsigned>(reply.status), response);
  MHD_destroy_response(response);
  if (result == MHD_YES) {
    r.answered = true;
    // Counted before a byte of the answer leaves: a client that reads the
    // metrics next must find its previous request in them.
    metrics.record(reply.status, Clock::now() - r.start);
  } else {
    log("cannot queue the answer " + std::to_string(reply.status) + " to " + r.method + " " +
        r.url);
  }
  return result;
}

Reply ApiServer::dispatch(MHD_Connection* c, Request& r) {
  try {
    return handle(c, r);
  } catch (const ServiceError& e) {
    return errorReply(e.httpStatus(), e.what());
  } catch (const std::exception& e) {
    log("internal error answering " + r.method + " " + r.url + ": " + e.what());
    return errorReply(500, std::string("internal error: ") + e.what());
  }
}

Reply ApiServer::handle(MHD_Connection* c, Request& r) {
  using http::Endpoint;
  const bool get = r.method == "GET" || r.method == "HEAD";
  switch (r.route.endpoint) {
    case Endpoint::Status:
      return jsonReply(200, service.status());
    case Endpoint::System:
      return jsonReply(200, service.system());
    case Endpoint::Scans: {
      if (get) return jsonReply(200, service.listScans());
      const std::string id = service.startScan(bodyObject(r.body, json::object()));
      Reply reply = jsonReply(202, json{{"id", id}});
      reply.headers.emplace_back(MHD_HTTP_HEADER_LOCATION, "/api/v1/scans/" + id);
      return reply;
    }
    case Endpoint::Scan: {
      if (get) {
        auto scan = service.scan(r.route.id);
        if (!scan) return errorReply(404, "no such scan: " + r.route.id);
        return jsonReply(200, *scan);
      }
      if (!service.deleteScan(r.route.id)) return errorReply(404, "no such scan: " + r.route.id);
      Reply reply;
      reply.status = 204;
      return reply;
    }
    case Endpoint::ScanFile: {
      const auto path = service.scanFile(r.route.id, r.route.name);
      auto file = path ? http::openRegularFile(*path) : std::nullopt;
      if (!file) {
        return errorReply(404, "scan " + r.route.id + " has no " + r.route.name + " (yet)");
      }
      Reply reply;
      reply.content_type = std::string(http::scanFileContentType(r.route.name));
      reply.file = std::move(file);
      return reply;
    }
    case Endpoint::ScanCameraCloud: {
      const auto path = service.scanCameraCloud(r.route.id, r.route.name);
      auto file = path ? http::openRegularFile(*path) : std::nullopt;
      if (!file) {
        return errorReply(404, "scan " + r.route.id + " has no cloud of camera " + r.route.name);
      }
      Reply reply;
      reply.content_type = "application/octet-stream";
      reply.file = std::move(file);
      return reply;
    }
    case Endpoint::Head: {
      if (get) {
        auto head = service.headInfo();
        if (!head) return errorReply(404, "no head extrinsics installed (PUT /api/v1/head)");
        return jsonReply(200, *head);
      }
      return jsonReply(200, service.installHead(r.body));
    }
    case Endpoint::Calibration: {
      if (get) return jsonReply(200, json{{"main", service.calibrationInfo("main")}});
      const char* arg = MHD_lookup_connection_value(c, MHD_GET_ARGUMENT_KIND, "camera");
      const std::string camera = arg != nullptr ? arg : "main";
      if (!isCameraName(camera)) {
        return errorReply(400, "camera: '" + camera + "' is not a camera name (" +
                                   std::string(kCameraNameRule) + ")");
      }
      return jsonReply(200, service.installCalibration(camera, r.body));
    }
    case Endpoint::CalibrationFile: {
      const auto path = service.calibrationFile(r.route.name);
      auto file = path ? http::openRegularFile(*path) : std::nullopt;
      if (!file) return errorReply(404, "no calibration installed for camera " + r.route.name);
      Reply reply;
      reply.content_type = "application/octet-stream";
      reply.file = std::move(file);
      return reply;
    }
    case Endpoint::SystemUpdate:  // streamed: beginUpdate and finishUpdate answer it
      return finishUpdate(r);
    case Endpoint::Events: {  // HEAD: the headers of a stream, no stream
      Reply reply;
      reply.content_type = "text/event-stream";
      return reply;
    }
    case Endpoint::Checks: {
      if (get) return jsonReply(200, service.listChecks());
      // No body is an empty one: the service names the keys it needs.
      const std::string id = service.startCheck(bodyObject(r.body, json::object()));
      Reply reply = jsonReply(202, json{{"id", id}});
      reply.headers.emplace_back(MHD_HTTP_HEADER_LOCATION, "/api/v1/scans/" + id);
      return reply;
    }
    case Endpoint::CalibrationSession: {
      if (get) {
        auto session = service.session();
        if (!session) return errorReply(404, "no calibration session");
        return jsonReply(200, *session);
      }
      Reply reply = jsonReply(201, service.startSession(bodyObject(r.body, nullptr)));
      reply.headers.emplace_back(MHD_HTTP_HEADER_LOCATION, "/api/v1/calibration/session");
      return reply;
    }
    case Endpoint::CalibrationBoards:  // answered by startCapture
    case Endpoint::FringeCheck:
      return errorReply(500, "internal error: a capture was not suspended");
    case Endpoint::FringePicture: {
      Reply reply;
      reply.content_type = "image/jpeg";
      reply.body = service.fringePicture(r.route.name);
      return reply;
    }
    case Endpoint::CalibrationPlanes:
      return jsonReply(202, service.capturePlane(bodyObject(r.body, json::object())));
    case Endpoint::CalibrationSolve:
      service.solveSession();
      return jsonReply(202, json{{"state", "solving"}});
    case Endpoint::CalibrationInstall:
      return jsonReply(200, service.installSession());
    case Endpoint::CalibrationRollback:
      return jsonReply(200, service.rollbackCalibration());
    case Endpoint::Cameras:
      return jsonReply(200, service.cameras());
    case Endpoint::Camera: {
      json controls;
      try {
        controls = json::parse(r.body);
      } catch (const json::exception& e) {
        return errorReply(400, std::string("the body is not valid JSON: ") + e.what());
      }
      if (!controls.is_object()) return errorReply(400, "the body must be a JSON object");
      return jsonReply(200, service.setCameraControls(r.route.name, controls));
    }
    case Endpoint::CameraStream: {  // HEAD: the headers of a stream, no stream
      Reply reply;
      reply.content_type = "multipart/x-mixed-replace; boundary=" + std::string(kLiveBoundary);
      return reply;
    }
    case Endpoint::CameraSnapshot:  // answered by startSnapshot
      break;
    case Endpoint::Metrics: {
      std::string text = service.metricsText();
      if (!text.empty() && text.back() != '\n') text += '\n';
      std::size_t clients = 0;
      {
        std::lock_guard lock(sse_mutex);
        clients = static_cast<std::size_t>(
            std::count_if(sse_clients.begin(), sse_clients.end(),
                          [](const auto& entry) { return !entry.second->is_live; }));
      }
      Reply reply;
      reply.body = text + metrics.text(clients);
      reply.content_type = "text/plain; version=0.0.4; charset=utf-8";
      return reply;
    }
    case Endpoint::Static:
      return staticFile(r);
    case Endpoint::None:
      break;
  }
  return errorReply(404, "no such endpoint");
}

Reply ApiServer::staticFile(const Request& r) const {
  if (options.web_root.empty()) return errorReply(404, "no web page is configured (web_root)");
  auto file = http::openStaticFile(options.web_root, r.route.name);
  if (!file) return errorReply(404, "no such file: /" + r.route.name);
  Reply reply;
  reply.content_type = std::string(http::staticContentType(r.route.name));
  // The page itself is always revalidated; its assets may be reused a while.
  reply.cache_control =
      reply.content_type.starts_with("text/html") ? "no-cache" : "public, max-age=300";
  reply.file = std::move(file);
  return reply;
}

MHD_Result ApiServer::startEvents(MHD_Connection* c, Request& r) {
  auto client = std::make_shared<SseClient>();
  // A first comment, so the client has the head and a first chunk at once
  // even when the service has nothing to say yet.
  client->pending = ": cylscan events\n\n";
  return startStream(c, r, client, "text/event-stream", kSseBlockSize, [this](SseClient& cl) {
    auto stream = service.subscribe();
    std::lock_guard lock(cl.mutex);
    cl.stream = std::move(stream);
  });
}

MHD_Result ApiServer::startLiveView(MHD_Connection* c, Request& r) {
  auto client = std::make_shared<SseClient>();
  client->is_live = true;
  const std::optional<bool> overlay = saturationOverlayAsked(c);
  if (!overlay) return answer(c, r, errorReply(400, "overlay: the only overlay is saturation"));
  LiveViewRequest request;
  request.camera = r.route.name;
  request.saturation_overlay = *overlay;
  const std::string type = "multipart/x-mixed-replace; boundary=" + std::string(kLiveBoundary);
  return startStream(c, r, client, type.c_str(), kLiveBlockSize, [&](SseClient& cl) {
    auto live = service.openLiveView(request);
    std::lock_guard lock(cl.mutex);
    cl.live = std::move(live);
  });
}

// Registers a stream (503 past max_sse_clients or while stopping), opens its
// source with `open` (a ServiceError is answered with its status) and starts
// the response that the pump feeds.
MHD_Result ApiServer::startStream(MHD_Connection* c, Request& r,
                                  const std::shared_ptr<SseClient>& client,
                                  const char* content_type, std::size_t block_size,
                                  const std::function<void(SseClient&)>& open) {
  client->owner = this;
  client->connection = c;
  if (const MHD_ConnectionInfo* info =
          MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD)) {
    client->fd = info->connect_fd;
  }
  {
    std::lock_guard lock(sse_mutex);
    if (stopping) return answer(c, r, errorReply(503, "the server is stopping"));
    if (sse_clients.size() >= options.max_sse_clients) {
      return answer(
          c, r,
          errorReply(503,
                     std::string(client->is_live ? "too many streams" : "too many event streams") +
                         " (at most " + std::to_string(options.max_sse_clients) + ")"));
    }
    sse_clients.emplace(client.get(), client);  // reserves the place
  }
  const auto unregister = [&] {
    std::lock_guard lock(sse_mutex);
    sse_clients.erase(client.get());
  };
  try {
    open(*client);
  } catch (const std::exception& e) {
    unregister();
    const auto* se = dynamic_cast<const ServiceError*>(&e);
    return answer(c, r,
                  errorReply(se != nullptr ? se->httpStatus() : 500,
                             std::string(client->is_live ? "no live view: "
                                                         : "cannot subscribe to events: ") +
                                 e.what()));
  }
  MHD_Response* response = MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, block_size, &sseRead,
                                                             client.get(), &sseFree);
  if (response == nullptr) {
    unregister();
    return answer(c, r, errorReply(500, "cannot create the stream"));
  }
  MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, content_type);
  MHD_add_response_header(response, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
  MHD_add_response_header(response, "X-Content-Type-Options", "nosniff");
  MHD_add_response_header(response, "X-Accel-Buffering", "no");
  const MHD_Result result = MHD_queue_response(c, MHD_HTTP_OK, response);
  MHD_destroy_response(response);  // on failure this frees the client (sseFree)
  if (result == MHD_YES) {
    r.answered = true;
    metrics.record(200, Clock::now() - r.start);
  }
  sse_cv.notify_all();  // the pump wakes for its first client
  return result;
}

// Opens the live view for one picture and suspends the request; the pump
// resumes it with the picture or the reason there is none.
MHD_Result ApiServer::startSnapshot(MHD_Connection* c, Request& r) {
  auto pending = std::make_shared<PendingReply>();
  pending->connection = c;
  pending->camera = r.route.name;
  pending->deadline = Clock::now() + kSnapshotTimeout;
  const std::optional<bool> overlay = saturationOverlayAsked(c);
  if (!overlay) return answer(c, r, errorReply(400, "overlay: the only overlay is saturation"));
  LiveViewRequest request;
  request.camera = r.route.name;
  request.saturation_overlay = *overlay;
  try {
    pending->live = service.openLiveView(request);
  } catch (const ServiceError& e) {
    return answer(c, r, errorReply(e.httpStatus(), std::string("no snapshot: ") + e.what()));
  } catch (const std::exception& e) {
    log("internal error opening a snapshot: " + std::string(e.what()));
    return answer(c, r, errorReply(500, std::string("internal error: ") + e.what()));
  }
  return suspend(c, r, std::move(pending));
}

MHD_Result ApiServer::suspend(MHD_Connection* c, Request& r,
                              std::shared_ptr<PendingReply> pending) {
  {
    std::lock_guard lock(sse_mutex);
    if (stopping) return answer(c, r, errorReply(503, "the server is stopping"));
    r.pending = pending;
    r.counted_pending = true;
    ++pending_in_flight;
    // Suspended before the pump can see it, so its resume always follows.
    MHD_suspend_connection(c);
    pending_replies.push_back(std::move(pending));
  }
  sse_cv.notify_all();
  return MHD_YES;
}

// A capture is a scan plan's frames: seconds, too long to hold a thread.
MHD_Result ApiServer::startCapture(MHD_Connection* c, Request& r, int status,
                                   const std::function<std::future<json>()>& start) {
  auto pending = std::make_shared<PendingReply>();
  pending->connection = c;
  pending->answer_status = status;
  pending->deadline = Clock::now() + kCaptureTimeout;
  try {
    pending->answer = start();
  } catch (const ServiceError& e) {
    return answer(c, r, errorReply(e.httpStatus(), e.what()));
  } catch (const std::exception& e) {
    log("internal error starting a capture: " + std::string(e.what()));
    return answer(c, r, errorReply(500, std::string("internal error: ") + e.what()));
  }
  return suspend(c, r, std::move(pending));
}

// The pump's part for snapshots: each gets its picture, the live view's end
// or a timeout as its reply, and is resumed.
void ApiServer::servePending() {
  std::vector<std::shared_ptr<PendingReply>> done;
  {
    std::lock_guard lock(sse_mutex);
    const auto now = Clock::now();
    std::erase_if(pending_replies, [&](const std::shared_ptr<PendingReply>& p) {
      std::optional<Reply> reply;
      if (p->answer.valid()) {
        if (p->answer.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
          try {
            reply = jsonReply(p->answer_status, p->answer.get());
          } catch (const ServiceError& e) {
            reply = errorReply(e.httpStatus(), e.what());
          } catch (const std::exception& e) {
            reply = errorReply(500, std::string("internal error: ") + e.what());
          }
        } else if (stopping) {
          reply = errorReply(503, "the server is stopping");
        } else if (now >= p->deadline) {
          reply = errorReply(503, "the capture took longer than " +
                                      std::to_string(kCaptureTimeout.count()) + " s");
        }
      } else if (auto frame = p->live->next(std::chrono::milliseconds(0))) {
        Reply ok;
        ok.content_type = "image/jpeg";
        ok.body = std::move(frame->jpeg);
        ok.headers.emplace_back("X-Cylscan-Focus", formatNumber(frame->focus));
        ok.headers.emplace_back("X-Cylscan-Saturated", formatNumber(frame->saturated));
        reply = std::move(ok);
      } else if (p->live->ended()) {
        reply = errorReply(p->live->endStatus() != 0 ? p->live->endStatus() : 503,
                           "no snapshot: " + p->live->endReason());
      } else if (stopping) {
        reply = errorReply(503, "the server is stopping");
      } else if (now >= p->deadline) {
        reply = errorReply(503, "no snapshot: camera " + p->camera + " gave no picture within " +
                                    std::to_string(kSnapshotTimeout.count()) + " s");
      }
      if (!reply) return false;
      std::lock_guard plock(p->mutex);
      p->reply = std::move(reply);
      done.push_back(p);
      return true;
    });
  }
  for (const auto& p : done) {
    if (p->live) p->live.reset();  // the head stops taking pictures for it
    MHD_resume_connection(p->connection);
  }
}

void ApiServer::completed(const Request& r) {
  if (r.holds_calibration_upload) calibration_upload = false;
  if (r.linger && r.fd >= 0) {
    // libmicrohttpd closes its descriptor after this; the duplicate keeps
    // the socket open (its answer sent, the write side shut) for draining.
    const int fd = ::fcntl(r.fd, F_DUPFD_CLOEXEC, 0);
    if (fd >= 0) {
      std::lock_guard lock(sse_mutex);
      if (stopping) {
        ::close(fd);
      } else {
        lingering.push_back(Lingering{fd, Clock::now() + kLingerTime, 0});
        sse_cv.notify_all();
      }
    }
  }
  if (r.counted_pending) {
    std::lock_guard lock(sse_mutex);
    --pending_in_flight;
    sse_cv.notify_all();
  }
}

void ApiServer::sseFreed(SseClient* client) {
  std::shared_ptr<SseClient> last;  // destroyed outside the lock
  {
    std::lock_guard lock(sse_mutex);
    const auto it = sse_clients.find(client);
    if (it != sse_clients.end()) {
      last = std::move(it->second);
      sse_clients.erase(it);
    }
  }
  sse_cv.notify_all();
}

// Moves events from the service into the streams' buffers, adds keepalives,
// and resumes the suspended streams that have something to send. It sleeps
// while there is no stream, else looks every kPumpTick; it never waits on a
// client (the service's queues are bounded and drop the oldest).
void ApiServer::pumpLoop() {
  std::vector<std::shared_ptr<SseClient>> clients;
  while (true) {
    {
      std::unique_lock lock(sse_mutex);
      sse_cv.wait(lock, [this] {
        return stopping || !sse_clients.empty() || !pending_replies.empty() || !lingering.empty();
      });
      if (stopping) return;
      sse_cv.wait_for(lock, kPumpTick, [this] { return stopping; });
      if (stopping) return;
      for (const auto& [key, client] : sse_clients)
        clients.push_back(client);
    }
    const auto now = Clock::now();
    for (const auto& client : clients) {
      if (client->gone) continue;
      std::lock_guard lock(client->mutex);
      if (!client->stream && !client->live) continue;  // still being subscribed
      if (client->live) {
        serveLive(*client, now);
      } else if (!client->ended) {
        while (client->pending.size() < kSsePendingLimit) {
          auto event = client->stream->next(std::chrono::milliseconds(0));
          if (!event) break;
          client->append(formatEvent(*event), now);
        }
        const std::uint64_t dropped = client->stream->dropped();
        if (dropped != client->dropped_seen) {
          client->append(": " + std::to_string(dropped - client->dropped_seen) +
                             " events dropped (slow reader)\n\n",
                         now);
          client->dropped_seen = dropped;
        }
        if (client->stream->closed()) client->ended = true;
        if (client->pending.empty() && now - client->last_output >= options.sse_keepalive) {
          client->append(": keepalive\n\n", now);
        }
      }
      if (client->suspended && (!client->pending.empty() || client->ended)) {
        client->suspended = false;
        MHD_resume_connection(client->connection);
      }
    }
    dropHungUp(clients);
    clients.clear();  // a freed client's stream (its subscription) ends here
    servePending();
    drainLingering(now);
  }
}

// Reads and drops what the lingering connections send, and closes each at
// its end of stream, an error, its deadline or its byte budget.
void ApiServer::drainLingering(Clock::time_point now) {
  std::vector<Lingering> work;
  {
    std::lock_guard lock(sse_mutex);
    work.swap(lingering);
  }
  if (work.empty()) return;
  std::vector<char> scratch(64u << 10);
  std::vector<Lingering> keep;
  for (Lingering& l : work) {
    bool done = now >= l.deadline || l.drained >= kLingerBytes;
    std::size_t this_tick = 0;
    while (!done && this_tick < kLingerBytesPerTick) {
      const ssize_t n = ::recv(l.fd, scratch.data(), scratch.size(), MSG_DONTWAIT);
      if (n > 0) {
        this_tick += static_cast<std::size_t>(n);
        l.drained += static_cast<std::size_t>(n);
        continue;
      }
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) break;
      done = true;  // the client closed its side, or the connection failed
    }
    if (done) {
      ::close(l.fd);
    } else {
      keep.push_back(l);
    }
  }
  std::lock_guard lock(sse_mutex);
  for (Lingering& l : keep)
    lingering.push_back(l);
}

// A live view's newest picture once the last one is sent (a slow client
// skips pictures instead of queueing them), and the closing boundary when it
// ends (client->mutex held).
void ApiServer::serveLive(SseClient& client, Clock::time_point now) {
  if (client.ended) return;
  if (client.pending.empty()) {
    if (auto frame = client.live->next(std::chrono::milliseconds(0)))
      client.append(formatPart(*frame), now);
  }
  if (client.live->ended()) {
    client.append("--" + std::string(kLiveBoundary) + "--\r\n", now);
    client.ended = true;
  }
}

// libmicrohttpd does not watch a suspended connection, so a client that
// went away would only be noticed at the next keepalive. The pump polls the
// suspended streams' sockets for a hang-up instead (one poll() per tick) and
// ends those streams at once. The sockets stay open meanwhile: a suspended
// connection is only resumed (and then maybe closed) by this thread.
void ApiServer::dropHungUp(const std::vector<std::shared_ptr<SseClient>>& clients) {
  std::vector<pollfd> fds;
  std::vector<SseClient*> polled;
  for (const auto& client : clients) {
    std::lock_guard lock(client->mutex);
    if (client->suspended && !client->gone && client->fd >= 0) {
      fds.push_back(pollfd{client->fd, POLLRDHUP, 0});
      polled.push_back(client.get());
    }
  }
  if (fds.empty() || ::poll(fds.data(), fds.size(), 0) <= 0) return;
  for (std::size_t i = 0; i < fds.size(); ++i) {
    if ((fds[i].revents & (POLLRDHUP | POLLHUP | POLLERR)) == 0) continue;
    SseClient& client = *polled[i];
    std::lock_guard lock(client.mutex);
    client.ended = true;
    client.pending.clear();
    if (client.suspended) {
      client.suspended = false;
      MHD_resume_connection(client.connection);
    }
  }
}

struct HttpApi::Impl {
  Impl(HeadService& service, HttpOptions options) : server(service, std::move(options)) {}
  ApiServer server;
};

HttpApi::HttpApi(HeadService& service, HttpOptions options)
    : impl_(std::make_unique<Impl>(service, std::move(options))) {
  impl_->server.start();
}

HttpApi::~HttpApi() {
  impl_->server.stop();
}

std::uint16_t HttpApi::port() const {
  return impl_->server.bound_port;
}

}  // namespace cylscan::firmware
