// SPDX-License-Identifier: Apache-2.0
#include "firmware/http/http_metrics.hpp"

#include <cstdio>

namespace cylscan::firmware::http {

void HttpMetrics::record(int status, std::chrono::duration<double> duration) {
  const double s = duration.count();
  std::lock_guard lock(mutex_);
  ++by_code_[status];
  ++count_;
  sum_ += s;
  for (std::size_t i = 0; i < kBuckets.size(); ++i) {
    if (s <= kBuckets[i]) {
      ++buckets_[i];
      break;
    }
  }
}

std::string HttpMetrics::text(std::size_t sse_clients) const {
  std::lock_guard lock(mutex_);
  std::string out;
  char line[256];
  out += "# HELP cylscan_http_requests_total HTTP requests answered, by status code.\n";
  out += "# TYPE cylscan_http_requests_total counter\n";
  for (const auto& [code, n] : by_code_) {
    std::snprintf(line, sizeof line, "cylscan_http_requests_total{code=\"%d\"} %llu\n", code,
                  static_cast<unsigned long long>(n));
    out += line;
  }
  out +=
      "# HELP cylscan_http_request_duration_seconds Time from a request's arrival to its queued "
      "answer.\n";
  out += "# TYPE cylscan_http_request_duration_seconds histogram\n";
  std::uint64_t cumulative = 0;
  for (std::size_t i = 0; i < kBuckets.size(); ++i) {
    cumulative += buckets_[i];
    std::snprintf(line, sizeof line,
                  "cylscan_http_request_duration_seconds_bucket{le=\"%g\"} %llu\n", kBuckets[i],
                  static_cast<unsigned long long>(cumulative));
    out += line;
  }
  std::snprintf(line, sizeof line,
                "cylscan_http_request_duration_seconds_bucket{le=\"+Inf\"} %llu\n"
                "cylscan_http_request_duration_seconds_sum %.9g\n"
                "cylscan_http_request_duration_seconds_count %llu\n",
                static_cast<unsigned long long>(count_), sum_,
                static_cast<unsigned long long>(count_));
  out += line;
  out += "# HELP cylscan_sse_clients Open event streams (GET /api/v1/events).\n";
  out += "# TYPE cylscan_sse_clients gauge\n";
  out += "cylscan_sse_clients " + std::to_string(sse_clients) + "\n";
  return out;
}

}  // namespace cylscan::firmware::http
