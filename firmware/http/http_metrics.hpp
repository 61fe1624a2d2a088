// SPDX-License-Identifier: Apache-2.0
// The HTTP layer's own Prometheus metrics: requests by status code, the
// time to answer them (a histogram) and the open event streams.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>

namespace cylscan::firmware::http {

class HttpMetrics {
 public:
  // One answered request; `duration`: from its headers to its answer's end.
  void record(int status, std::chrono::duration<double> duration);
  // Text format 0.0.4: cylscan_http_requests_total{code}, the histogram
  // cylscan_http_request_duration_seconds and the gauge cylscan_sse_clients.
  std::string text(std::size_t sse_clients) const;

  static constexpr std::array<double, 10> kBuckets{0.001, 0.0025, 0.005, 0.01, 0.025,
                                                   0.05,  0.1,    0.25,  1.0,  5.0};

 private:
  mutable std::mutex mutex_;
  std::map<int, std::uint64_t> by_code_;
  std::array<std::uint64_t, kBuckets.size()> buckets_{};  // not cumulative
  std::uint64_t count_ = 0;
  double sum_ = 0.0;
};

}  // namespace cylscan::firmware::http
