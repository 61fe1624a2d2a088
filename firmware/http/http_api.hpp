// The daemon's HTTP API (docs/http-api.md) on libmicrohttpd: routes requests
// to a HeadService, checks the bearer token, enforces the size limits, streams
// server-sent events and serves the web page's static files. It never runs on
// the real-time thread and never blocks the head: it only calls HeadService,
// whose calls return at once.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "firmware/daemon/head_service.hpp"

namespace cylscan::firmware {

struct HttpOptions {
  std::string address = "127.0.0.1";  // IPv4 or IPv6 literal to bind
  std::uint16_t port = 8080;          // 0: any free port (see HttpApi::port())
  std::string token;                  // empty: no authentication
  bool allow_loopback_without_token = false;
  std::filesystem::path web_root;     // empty: no page
  std::size_t max_calibration_bytes = 128u << 20;
};

class HttpApi {
 public:
  // Binds and starts serving; std::runtime_error naming the address when it
  // cannot bind.
  HttpApi(HeadService& service, HttpOptions options);
  ~HttpApi();  // stops serving; open event streams are closed
  HttpApi(const HttpApi&) = delete;
  HttpApi& operator=(const HttpApi&) = delete;

  std::uint16_t port() const;  // the bound port

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cylscan::firmware
