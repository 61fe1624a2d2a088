// SPDX-License-Identifier: Apache-2.0
// What the daemon's service tests share: a service's options on a board and
// a data directory, and the ServiceError a call throws.
#pragma once

#include <filesystem>

#include "firmware/daemon/scan_service.hpp"

namespace cylscan::test_support {

inline firmware::ScanServiceOptions serviceOptions(const std::filesystem::path& board,
                                                   const std::filesystem::path& data_dir) {
  firmware::ScanServiceOptions o;
  o.board = board;
  o.data_dir = data_dir;
  o.version = "test";
  return o;
}

// The ServiceError of `f`, which must throw one (status 0 when it did not).
template <typename F>
firmware::ServiceError errorOf(F&& f) {
  try {
    f();
  } catch (const firmware::ServiceError& e) {
    return e;
  }
  return firmware::ServiceError(0, "(no ServiceError)");
}

}  // namespace cylscan::test_support
