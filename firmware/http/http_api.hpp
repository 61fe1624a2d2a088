// SPDX-License-Identifier: Apache-2.0
// The daemon's HTTP API (docs/http-api.md) on libmicrohttpd: routes requests
// to a HeadService, checks the bearer token, enforces the size limits, streams
// server-sent events and serves the web page's static files. It never runs on
// the real-time thread and never blocks the head: it only calls HeadService,
// whose calls return at once.
//
// Threads: libmicrohttpd's internal poll threads (a pool of
// `worker_threads`; no thread per connection) and one event pump that moves
// HeadService events into the idle event streams, which are suspended
// connections in between (they hold no thread).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "firmware/daemon/head_service.hpp"

namespace cylscan::firmware {

struct HttpOptions {
  std::string address = "127.0.0.1";          // IPv4 or IPv6 literal to bind
  std::uint16_t port = 8080;                  // 0: any free port (see HttpApi::port())
  std::string token;                          // empty: no authentication
  bool allow_loopback_without_token = false;  // peers 127.0.0.1 and ::1 only
  std::filesystem::path web_root;             // empty: no page
  std::size_t max_calibration_bytes = 128u << 20;
  std::size_t max_json_bytes = 64u << 10;   // other request bodies
  std::size_t max_header_bytes = 8u << 10;  // request line + headers, else 431

  // Connections: all of them, from one peer address, and event streams.
  unsigned max_connections = 256;
  unsigned max_connections_per_ip = 64;
  unsigned max_sse_clients = 64;                   // more: 503
  std::chrono::seconds connection_timeout{60};     // idle connections are closed
  unsigned worker_threads = 2;                     // libmicrohttpd's thread pool
  std::chrono::milliseconds sse_keepalive{15000};  // ": keepalive" period

  // Where errors go (one line each, never a token); empty: stderr.
  std::function<void(std::string_view)> log;
};

class HttpApi {
 public:
  // Binds and starts serving; std::runtime_error naming the address when it
  // cannot bind (or the address is not an IP literal).
  HttpApi(HeadService& service, HttpOptions options);
  ~HttpApi();  // stops serving; open event streams are ended first
  HttpApi(const HttpApi&) = delete;
  HttpApi& operator=(const HttpApi&) = delete;

  std::uint16_t port() const;  // the bound port

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cylscan::firmware
