// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/metrics.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace cylscan::firmware {

void LabelledCounter::inc(const std::string& label_value, std::uint64_t n) {
  const std::lock_guard lock(mutex_);
  values_[label_value] += n;
}

std::uint64_t LabelledCounter::value(const std::string& label_value) const {
  const std::lock_guard lock(mutex_);
  auto it = values_.find(label_value);
  return it == values_.end() ? 0 : it->second;
}

std::map<std::string, std::uint64_t> LabelledCounter::values() const {
  const std::lock_guard lock(mutex_);
  return values_;
}

Histogram::Histogram(std::vector<double> upper_bounds) {
  for (std::size_t i = 0; i < upper_bounds.size(); ++i) {
    if (!std::isfinite(upper_bounds[i]) || (i > 0 && upper_bounds[i] <= upper_bounds[i - 1]))
      throw std::invalid_argument("Histogram: the bounds must be finite and increasing");
  }
  s_.bounds = std::move(upper_bounds);
  s_.counts.assign(s_.bounds.size(), 0);
}

void Histogram::observe(double value) {
  const std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < s_.bounds.size(); ++i)
    if (value <= s_.bounds[i]) ++s_.counts[i];
  ++s_.count;
  s_.sum += value;
}

Histogram::Snapshot Histogram::snapshot() const {
  const std::lock_guard lock(mutex_);
  return s_;
}

Histogram::Snapshot foldJitter(const drivers::JitterStats::Snapshot& jitter,
                               const std::vector<double>& bounds_s) {
  Histogram::Snapshot h;
  h.bounds = bounds_s;
  h.counts.assign(bounds_s.size(), 0);
  const double width = static_cast<double>(jitter.bucket_width.count()) * 1e-9;
  for (std::size_t i = 0; i < jitter.buckets.size(); ++i) {
    const std::uint64_t n = jitter.buckets[i];
    if (n == 0) continue;
    const double upper = width * static_cast<double>(i + 1);
    for (std::size_t b = 0; b < bounds_s.size(); ++b)
      if (upper <= bounds_s[b] * (1 + 1e-12)) h.counts[b] += n;
    h.count += n;
    h.sum += static_cast<double>(n) * width * (static_cast<double>(i) + 0.5);
  }
  return h;
}

const std::vector<double>& defaultLatenessBoundsSeconds() {
  static const std::vector<double> bounds = {1e-6,   2e-6,   5e-6,   10e-6, 20e-6, 50e-6,
                                             100e-6, 200e-6, 500e-6, 1e-3,  2e-3};
  return bounds;
}

std::string formatMetricValue(double value) {
  if (std::isnan(value)) return "NaN";
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, value);
  return ec == std::errc() ? std::string(buf, end) : "NaN";
}

std::string escapeLabelValue(std::string_view value) {
  std::string out;
  for (char c : value) {
    if (c == '\\')
      out += "\\\\";
    else if (c == '"')
      out += "\\\"";
    else if (c == '\n')
      out += "\\n";
    else
      out += c;
  }
  return out;
}

void MetricsWriter::header(std::string_view name, std::string_view help, std::string_view type) {
  text_ += "# HELP ";
  text_ += name;
  text_ += ' ';
  text_ += help;
  text_ += "\n# TYPE ";
  text_ += name;
  text_ += ' ';
  text_ += type;
  text_ += '\n';
}

void MetricsWriter::counter(std::string_view name, std::string_view help, std::uint64_t value) {
  header(name, help, "counter");
  text_ += std::string(name) + " " + std::to_string(value) + "\n";
}

void MetricsWriter::counter(std::string_view name, std::string_view help, std::string_view label,
                            const std::map<std::string, std::uint64_t>& values) {
  header(name, help, "counter");
  for (const auto& [v, n] : values)
    text_ += std::string(name) + "{" + std::string(label) + "=\"" + escapeLabelValue(v) + "\"} " +
             std::to_string(n) + "\n";
}

void MetricsWriter::gauge(std::string_view name, std::string_view help, double value) {
  header(name, help, "gauge");
  text_ += std::string(name) + " " + formatMetricValue(value) + "\n";
}

void MetricsWriter::gauge(std::string_view name, std::string_view help, std::string_view label,
                          const std::map<std::string, double>& values) {
  header(name, help, "gauge");
  for (const auto& [v, x] : values)
    text_ += std::string(name) + "{" + std::string(label) + "=\"" + escapeLabelValue(v) + "\"} " +
             formatMetricValue(x) + "\n";
}

void MetricsWriter::histogram(std::string_view name, std::string_view help,
                              const Histogram::Snapshot& h) {
  header(name, help, "histogram");
  const std::string n(name);
  for (std::size_t i = 0; i < h.bounds.size(); ++i)
    text_ += n + "_bucket{le=\"" + formatMetricValue(h.bounds[i]) + "\"} " +
             std::to_string(h.counts[i]) + "\n";
  text_ += n + "_bucket{le=\"+Inf\"} " + std::to_string(h.count) + "\n";
  text_ += n + "_sum " + formatMetricValue(h.sum) + "\n";
  text_ += n + "_count " + std::to_string(h.count) + "\n";
}

}  // namespace cylscan::firmware
