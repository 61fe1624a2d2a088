// SPDX-License-Identifier: Apache-2.0
// Prometheus metrics (text exposition format 0.0.4): a counter, a histogram
// with fixed upper bounds, and their rendering. Thread-safe; used by the
// service (scans, frames, real-time lateness) and the HTTP layer (requests).
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/jitter_stats.hpp"

namespace cylscan::firmware {

class Counter {
 public:
  void inc(std::uint64_t n = 1) noexcept { value_.fetch_add(n, std::memory_order_relaxed); }
  std::uint64_t value() const noexcept { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> value_{0};
};

// A counter per value of one label, e.g. cylscan_scans_total{result="done"}.
class LabelledCounter {
 public:
  void inc(const std::string& label_value, std::uint64_t n = 1);
  std::uint64_t value(const std::string& label_value) const;
  std::map<std::string, std::uint64_t> values() const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::uint64_t> values_;
};

class Histogram {
 public:
  struct Snapshot {
    std::vector<double> bounds;         // upper bounds, increasing (+Inf implied)
    std::vector<std::uint64_t> counts;  // cumulative: observations <= bounds[i]
    std::uint64_t count = 0;            // all observations (the +Inf bucket)
    double sum = 0;
  };

  // std::invalid_argument unless the bounds are finite and increasing.
  explicit Histogram(std::vector<double> upper_bounds);
  void observe(double value);
  Snapshot snapshot() const;

 private:
  mutable std::mutex mutex_;
  Snapshot s_;
};

// The lateness histogram of a JitterStats snapshot (1 µs buckets) folded into
// Prometheus buckets with upper bounds `bounds_s` (seconds). A fine bucket
// counts at a bound when its upper edge is at or below it; the sum takes each
// fine bucket's middle (so it is within half a microsecond per edge).
Histogram::Snapshot foldJitter(const drivers::JitterStats::Snapshot& jitter,
                               const std::vector<double>& bounds_s);
// 1, 2, 5, 10, 20, 50, 100, 200, 500 µs, 1, 2 ms.
const std::vector<double>& defaultLatenessBoundsSeconds();

// Appends the metric families to a text exposition.
class MetricsWriter {
 public:
  void counter(std::string_view name, std::string_view help, std::uint64_t value);
  void counter(std::string_view name, std::string_view help, std::string_view label,
               const std::map<std::string, std::uint64_t>& values);
  void gauge(std::string_view name, std::string_view help, double value);
  void gauge(std::string_view name, std::string_view help, std::string_view label,
             const std::map<std::string, double>& values);
  void histogram(std::string_view name, std::string_view help, const Histogram::Snapshot& h);
  const std::string& text() const { return text_; }

 private:
  void header(std::string_view name, std::string_view help, std::string_view type);
  std::string text_;
};

// A number as Prometheus writes it ("+Inf", "NaN", shortest round-trip otherwise).
std::string formatMetricValue(double value);
// A label value escaped (backslash, double quote, newline).
std::string escapeLabelValue(std::string_view value);

}  // namespace cylscan::firmware
