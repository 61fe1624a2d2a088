// SPDX-License-Identifier: Apache-2.0
// The bearer-token check: bearerToken on an Authorization header value and
// tokenEquals against a token. The input is "EXPECTED\nHEADER VALUE" (no
// newline: the whole input is the header, checked against a fixed token).
// Checks that a parsed token is part of the header and that tokenEquals
// agrees with plain equality.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string_view>

#include "firmware/http/auth.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

void require(bool ok, const char* what) {
  if (!ok) throw std::logic_error(what);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace http = cylscan::firmware::http;
  const std::string_view input = cylscan::fuzz::asText(data, size);
  std::string_view expected = "s3cret-token";
  std::string_view header = input;
  if (const std::size_t nl = input.find('\n'); nl != std::string_view::npos) {
    expected = input.substr(0, nl);
    header = input.substr(nl + 1);
  }
  require(http::tokenEquals(expected, expected), "a token does not equal itself");
  require(http::tokenEquals(expected, header) == (expected == header),
          "tokenEquals disagrees with ==");
  if (const auto token = http::bearerToken(header)) {
    require(token->data() >= header.data() &&
                token->data() + token->size() <= header.data() + header.size(),
            "the token is not inside the header");
    require(header.size() > token->size(), "a token without a scheme");
    require(http::tokenEquals(*token, *token), "a parsed token does not equal itself");
    require(http::tokenEquals(expected, *token) == (expected == *token),
            "tokenEquals disagrees with == on a parsed token");
  }
  return 0;
}
