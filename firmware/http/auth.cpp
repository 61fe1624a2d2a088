// SPDX-License-Identifier: Apache-2.0
#include "firmware/http/auth.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <cstring>

namespace cylscan::firmware::http {

bool tokenEquals(std::string_view expected, std::string_view given) {
  // A fixed-length loop over the expected token: no early exit, and a
  // shorter `given` is read as if padded (its bytes are never read past its
  // end). `volatile` keeps the compiler from turning it into memcmp.
  volatile unsigned char diff = expected.size() == given.size() ? 0 : 1;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const unsigned char g = i < given.size() ? static_cast<unsigned char>(given[i]) : 0;
    diff = diff | static_cast<unsigned char>(static_cast<unsigned char>(expected[i]) ^ g);
  }
  return diff == 0;
}

std::optional<std::string_view> bearerToken(std::string_view authorization) {
  constexpr std::string_view kScheme = "bearer ";
  if (authorization.size() <= kScheme.size()) return std::nullopt;
  for (std::size_t i = 0; i < kScheme.size(); ++i) {
    char c = authorization[i];
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    if (c != kScheme[i]) return std::nullopt;
  }
  std::string_view token = authorization.substr(kScheme.size());
  while (!token.empty() && (token.front() == ' ' || token.front() == '\t'))
    token.remove_prefix(1);
  while (!token.empty() && (token.back() == ' ' || token.back() == '\t'))
    token.remove_suffix(1);
  if (token.empty()) return std::nullopt;
  return token;
}

bool isLoopbackPeer(const sockaddr* peer) {
  if (peer == nullptr) return false;
  if (peer->sa_family == AF_INET) {
    sockaddr_in v4{};
    std::memcpy(&v4, peer, sizeof v4);
    return ntohl(v4.sin_addr.s_addr) == INADDR_LOOPBACK;
  }
  if (peer->sa_family == AF_INET6) {
    sockaddr_in6 v6{};
    std::memcpy(&v6, peer, sizeof v6);
    if (IN6_IS_ADDR_LOOPBACK(&v6.sin6_addr)) return true;
    if (IN6_IS_ADDR_V4MAPPED(&v6.sin6_addr)) {
      const auto* b = v6.sin6_addr.s6_addr;
      return b[12] == 127 && b[13] == 0 && b[14] == 0 && b[15] == 1;
    }
  }
  return false;
}

}  // namespace cylscan::firmware::http
