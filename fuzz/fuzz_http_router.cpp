// SPDX-License-Identifier: Apache-2.0
// The HTTP API's pure router: a method and a percent-decoded path. The input
// is "METHOD\nPATH" (no newline: all of it is the path of a GET). Checks what
// router.hpp promises: a refused or unknown path is never routed, a route is
// either an error status or an endpoint, and what it hands on (id, name)
// holds no '..' segment, backslash, NUL, control character or '%'.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>

#include "firmware/http/router.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

using cylscan::firmware::http::Endpoint;

void require(bool ok, const char* what) {
  if (!ok) throw std::logic_error(what);
}

bool safeComponent(std::string_view s) {
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f || c == '\\' || c == '%') return false;
  }
  // No "." or ".." segment and no empty segment.
  std::size_t start = 0;
  while (start <= s.size()) {
    const std::size_t end = std::min(s.find('/', start), s.size());
    const std::string_view seg = s.substr(start, end - start);
    if (seg.empty() || seg == "." || seg == "..") return false;
    start = end + 1;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input = cylscan::fuzz::asText(data, size);
  std::string_view method = "GET";
  std::string_view path = input;
  if (const std::size_t nl = input.find('\n'); nl != std::string_view::npos) {
    method = input.substr(0, nl);
    path = input.substr(nl + 1);
  }
  namespace http = cylscan::firmware::http;
  const http::Route r = http::route(method, path);
  require(r.status == 0 || r.status == 400 || r.status == 404 || r.status == 405,
          "route status outside 0/400/404/405");
  require(r.param_status == 0 || r.param_status == 404, "param_status outside 0/404");
  if (r.status != 0) require(!r.error.empty(), "an error status without a message");
  if (r.status == 405) require(!r.allow.empty(), "405 without Allow");
  if (r.status == 0) {
    require(r.endpoint != Endpoint::None, "status 0 without an endpoint");
    require(!path.empty() && path.front() == '/', "routed a path not starting with '/'");
    if (r.param_status == 0) {
      if (!r.id.empty()) require(safeComponent(r.id), "unsafe scan id handed on");
      if (r.endpoint == Endpoint::ScanFile || r.endpoint == Endpoint::CalibrationFile ||
          r.endpoint == Endpoint::Static)
        require(r.name.empty() || safeComponent(r.name), "unsafe file name handed on");
    }
    if (r.endpoint == Endpoint::Static) {
      require(!path.starts_with("/api/"), "an /api/ path routed to the static files");
      (void)http::staticContentType(r.name);
    }
    if (r.endpoint == Endpoint::ScanFile && r.param_status == 0)
      (void)http::scanFileContentType(r.name);
    (void)http::needsToken(r.endpoint);
  }
  return 0;
}
