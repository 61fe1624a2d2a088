// SPDX-License-Identifier: Apache-2.0
// The bearer-token check of the HTTP API, without sockets.
#pragma once

#include <optional>
#include <string_view>

struct sockaddr;

namespace cylscan::firmware::http {

// Whether `given` equals `expected`. The time taken depends only on
// expected.size(): every byte of `expected` is compared, whatever `given`
// is (a wrong length, an early difference).
bool tokenEquals(std::string_view expected, std::string_view given);

// The token of an "Authorization: Bearer TOKEN" header value (the scheme is
// case-insensitive); nullopt for any other form.
std::optional<std::string_view> bearerToken(std::string_view authorization);

// Whether the peer is 127.0.0.1 or ::1 (also as ::ffff:127.0.0.1); nullptr: no.
bool isLoopbackPeer(const sockaddr* peer);

}  // namespace cylscan::firmware::http
