// SPDX-License-Identifier: Apache-2.0
#include "firmware/fringe_check.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <vector>

namespace cylscan::firmware {
namespace {

// The value at quantile q of `values` (reordered), 0 when there is none.
double quantile(std::vector<float>& values, double q) {
  if (values.empty()) return 0;
  const auto k = static_cast<std::ptrdiff_t>(std::min(
      values.size() - 1, static_cast<std::size_t>(q * static_cast<double>(values.size()))));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[static_cast<std::size_t>(k)];
}

}  // namespace

std::string_view toString(ExposureAdvice advice) {
  switch (advice) {
    case ExposureAdvice::kRaise:
      return "raise";
    case ExposureAdvice::kLower:
      return "lower";
    case ExposureAdvice::kRight:
      break;
  }
  return "right";
}

FringeQuality measureFringes(const algo::PhaseMaps& maps, const algo::PhaseOptions& options) {
  const algo::PhaseOptions& o = options;
  if (o.bit_depth < 8 || o.bit_depth > 16 || !(o.min_modulation >= 0))
    throw std::invalid_argument("measureFringes: the engine's options must be resolved");
  const cv::Mat& b = maps.modulation_high;
  const cv::Mat& a = maps.texture;
  const cv::Mat& invalid = maps.invalid;
  if (b.empty() || b.type() != CV_32FC1 || a.size() != b.size() || a.type() != CV_32FC1 ||
      invalid.size() != b.size() || invalid.type() != CV_8UC1)
    throw std::invalid_argument(
        "measureFringes: the maps need modulation_high, texture (CV_32FC1) "
        "and invalid (CV_8UC1) of one size");
  const double full_scale = (1 << o.bit_depth) - 1;
  const double pixels = static_cast<double>(b.total());
  std::vector<float> lit_modulation;
  std::vector<float> crests;
  lit_modulation.reserve(b.total());
  crests.reserve(b.total());
  std::size_t usable = 0;
  std::size_t saturated = 0;
  std::size_t saturated_lit = 0;
  FringeQuality q;
  q.picture.create(b.size(), CV_8UC3);
  // White is B = full/2: a sinusoid A ± B spanning the whole range.
  const double grey_per_count = 255.0 / (full_scale / 2);
  for (int y = 0; y < b.rows; ++y) {
    const float* by = b.ptr<float>(y);
    const float* ay = a.ptr<float>(y);
    const std::uint8_t* iy = invalid.ptr<std::uint8_t>(y);
    auto* py = q.picture.ptr<cv::Vec3b>(y);
    for (int x = 0; x < b.cols; ++x) {
      const bool is_lit = std::isfinite(by[x]) && by[x] >= o.min_modulation;
      const bool is_saturated = (iy[x] & algo::kSaturated) != 0;
      if (is_lit) {
        lit_modulation.push_back(by[x]);
        crests.push_back(ay[x] + by[x]);
      }
      if (iy[x] == algo::kValid) ++usable;
      if (is_saturated) {
        ++saturated;
        if (is_lit) ++saturated_lit;
        py[x] = cv::Vec3b(0, 0, 255);
      } else {
        const double grey =
            std::isfinite(by[x]) ? std::clamp(by[x] * grey_per_count, 0.0, 255.0) : 0;
        const auto g = static_cast<std::uint8_t>(std::lround(grey));
        py[x] = cv::Vec3b(g, g, g);
      }
    }
  }
  q.lit = static_cast<double>(lit_modulation.size()) / pixels;
  q.usable = static_cast<double>(usable) / pixels;
  q.saturated = static_cast<double>(saturated) / pixels;
  q.modulation_median = quantile(lit_modulation, 0.5);
  q.peak = quantile(crests, 0.995) / full_scale;
  const double saturated_share_of_lit =
      lit_modulation.empty() ? 0 : static_cast<double>(saturated_lit) / lit_modulation.size();
  if (saturated_share_of_lit > kMaxSaturatedShare) {
    q.advice = ExposureAdvice::kLower;
  } else if (q.peak < kMinPeakShare) {
    q.advice = ExposureAdvice::kRaise;
  }
  return q;
}

}  // namespace cylscan::firmware
