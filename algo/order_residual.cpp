// SPDX-License-Identifier: Apache-2.0
#include "algo/order_residual.hpp"

#include <algorithm>
#include <array>
#include <cstdlib>

namespace cylscan::algo {

ResidualStatistics measureResiduals(std::span<std::int32_t> residuals, int bits) {
  ResidualStatistics out;
  out.samples = residuals.size();
  if (residuals.size() < kMinResidualSamples) return out;
  const std::int64_t unit = std::int64_t{1} << bits;
  const std::int64_t half = unit >> 1;

  constexpr int kBins = 64;
  std::array<std::int64_t, kBins> histogram{};
  for (const std::int32_t r : residuals) {
    const auto bin = static_cast<std::size_t>((r + half) >> (bits - 6));
    ++histogram[bin & (kBins - 1)];
  }
  int peak = 0;
  std::int64_t best = -1;
  for (int b = 0; b < kBins; ++b) {
    const std::int64_t smoothed = histogram[static_cast<std::size_t>((b + kBins - 1) % kBins)] +
                                  2 * histogram[static_cast<std::size_t>(b)] +
                                  histogram[static_cast<std::size_t>((b + 1) % kBins)];
    if (smoothed > best) {  // the first of equal peaks: deterministic
      best = smoothed;
      peak = b;
    }
  }
  const std::int64_t bin_width = unit / kBins;
  const std::int32_t peak_centre = wrapResidual(peak * bin_width + bin_width / 2 - half, bits);

  // The mean over the residuals within ±1/8 turn, re-centred three times from
  // the peak: far residuals (wrong phases at edges and in shadows) would pull
  // a plain circular mean, and the re-centring makes the window symmetric
  // about the centre, so it neither truncates the noise one-sidedly nor lets
  // the outliers inside it pull towards the peak bin (each pass divides
  // that pull by about ten).
  out.centre = peak_centre;
  for (int pass = 0; pass < 3; ++pass) {
    std::int64_t sum = 0;
    std::int64_t count = 0;
    for (const std::int32_t r : residuals) {
      const std::int32_t d = wrapResidual(std::int64_t{r} - out.centre, bits);
      if (std::abs(d) < unit / 8) {
        sum += d;
        ++count;
      }
    }
    // count > 0: the peak bin's residuals are within 1/128 turn of the first
    // centre, and each pass moves the centre towards them.
    out.centre = wrapResidual(out.centre + sum / count, bits);
  }

  for (std::int32_t& r : residuals)
    r = std::abs(wrapResidual(std::int64_t{r} - out.centre, bits));
  const auto middle = residuals.begin() + static_cast<std::ptrdiff_t>(residuals.size() / 2);
  std::nth_element(residuals.begin(), middle, residuals.end());
  out.spread = static_cast<std::int32_t>(std::int64_t{*middle} * 14826 / 10000);
  // The upper tail lies beyond the median: select within it only.
  const auto tail = residuals.begin() +
                    static_cast<std::ptrdiff_t>(residuals.size() - 1 - residuals.size() / 1000);
  std::nth_element(middle, tail, residuals.end());
  out.reach = *tail;
  const std::int64_t far_from = unit * 7 / 16;
  out.near_antipode = static_cast<std::size_t>(
      std::count_if(tail, residuals.end(), [far_from](std::int32_t r) { return r > far_from; }));
  return out;
}

std::int32_t residualBoundForSpread(std::int32_t spread, int bits) {
  const std::int64_t unit = std::int64_t{1} << bits;  // 2π
  const std::int64_t sigma = spread;
  const std::int64_t bound = std::min(6 * sigma, unit - sigma * 9 / 2);
  return static_cast<std::int32_t>(std::clamp(bound, unit / 4, unit * 9 / 20));
}

std::int32_t residualBound(const ResidualStatistics& stats, int bits) {
  const std::int64_t unit = std::int64_t{1} << bits;
  const std::int64_t from_spread = residualBoundForSpread(stats.spread, bits);
  if (stats.near_antipode > stats.samples / kAntipodeSamplesPerOutlier)
    return static_cast<std::int32_t>(from_spread);
  const std::int64_t in_gap = stats.reach + (unit / 2 - stats.reach) / 2;
  return static_cast<std::int32_t>(
      std::clamp(std::max(from_spread, in_gap), unit / 4, unit * 9 / 20));
}

}  // namespace cylscan::algo
